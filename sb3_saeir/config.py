"""rl-zoo style YAML configs: one file per method in ``zoo_configs/``, one entry per task id (the model built from an
entry: :meth:`sb3_saeir.experiment.Experiment.build`).

Entry keys (rl-zoo's vocabulary): ``n_timesteps`` (agent-steps), ``n_envs`` (number of *games*; the vec env has
``n_envs * n_agents`` slots), ``num_cpus`` (env worker processes, 0 by default), ``policy``, ``policy_kwargs`` (a dict
or a string evaluated with ``nn`` in scope, as rl-zoo does), ``env_kwargs``, ``callback`` (``"module.Class"`` or
``{"module.Class": {kwargs}}`` or a list of these); every other key is a constructor argument of the method's
algorithm class. The command lines' own options and their checks are :mod:`sb3_saeir.command_line`.
"""

from __future__ import annotations

import importlib
import inspect
import os
import re
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3 import PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv
from torch import nn

from sb3_saeir.common.run_state import read_zip_data, saved_policy_class
from sb3_saeir.mappo import MAPPO
from sb3_saeir.saeir_ppo import SAEIR_PPO

# Method name -> algorithm class. Baselines and ablations share MAPPO's machinery; their YAML says what differs.
ALGOS: dict[str, type[OnPolicyAlgorithm]] = {
    "saeir_ppo": SAEIR_PPO,
    "mappo": MAPPO,
    "sn_mappo": MAPPO,
    "rnd": MAPPO,
    "elign": MAPPO,
    "mshg_only": MAPPO,
    "sae_only": MAPPO,
    "ippo": PPO,
}

# Policy keywords that the algorithm sets itself (from the env and its own ``normalize_values``), not a config.
ALGORITHM_POLICY_KWARGS = ("n_agents", "normalize_values")
# Keys of a config entry that are not constructor arguments of the algorithm.
CONFIG_KEYS = ("n_timesteps", "n_envs", "num_cpus", "env_kwargs", "policy", "policy_kwargs", "callback")
# Games of a config entry without ``n_envs``.
DEFAULT_N_GAMES = 8


class ConfigError(ValueError):
    """A bad command line or config: the message names the problem and the valid choices."""


class UnknownAlgorithmError(ConfigError, KeyError):
    """A method name that is not a key of :data:`ALGOS` (:func:`check_algo`); a ``KeyError`` too, as a lookup of it
    in :data:`ALGOS` would raise."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


def check_algo(algo: str) -> None:
    """Refuse a method name that is not a key of :data:`ALGOS` (every command and :class:`~sb3_saeir.experiment.Experiment`
    check it here, with one message).

    :param algo: the method name (``--algo``)
    :raises UnknownAlgorithmError: naming it and the valid choices
    """
    if algo not in ALGOS:
        raise UnknownAlgorithmError(f"unknown algorithm {algo!r}; valid choices: {', '.join(sorted(ALGOS))}.")


# ------------------------------------------------------------------------------------------------ YAML
class ConfigLoader(yaml.SafeLoader):
    """PyYAML's safe loader with two fixes for config files and ``-params`` values.

    - Numbers as rl-zoo3 users write them (``5e-4``, ``1e6``, ``1.5E-3``, ``-1e-2``) are floats: YAML 1.1 (PyYAML)
      only reads ``5.0e-4`` as a number and leaves ``5e-4`` a string.
    - A key given twice in one mapping is refused (PyYAML keeps the last value without a word).
    """

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise ConfigError(f"duplicate key {key!r} (line {key_node.start_mark.line + 1}): give each key once.")
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


# PyYAML's float resolver, with the dot optional and the exponent sign optional (YAML 1.2's float syntax)
_FLOAT = re.compile(
    r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.VERBOSE,
)
ConfigLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:float"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
ConfigLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT, list("-+0123456789."))


def load_yaml(stream: Any) -> Any:
    """Parse YAML (a string or an open file) with :class:`ConfigLoader`: what every config reader of the package uses.

    :raises ~sb3_saeir.config.ConfigError: on a duplicate key
    :raises yaml.YAMLError: on invalid YAML
    """
    return yaml.load(stream, Loader=ConfigLoader)


def parse_params(items: list[str] | None) -> dict[str, Any]:
    """``-params key:value key=value ...`` -> dict, values parsed as YAML (numbers such as ``5e-4``, booleans, lists,
    dicts)."""
    params: dict[str, Any] = {}
    for item in items or []:
        separator = min((i for i in (item.find(":"), item.find("=")) if i > 0), default=-1)
        if separator < 0:
            raise ConfigError(f"-params entry {item!r} is not key:value (or key=value).")
        key, raw = item[:separator], item[separator + 1 :]
        if key in params:
            raise ConfigError(f"-params {key} is given twice: give each key once.")
        try:
            params[key] = load_yaml(raw)
        except yaml.YAMLError as error:
            problem = getattr(error, "problem", None) or str(error).replace("\n", " ")
            raise ConfigError(f"-params {key}: cannot parse {raw!r} ({problem}).") from error
        except ConfigError as error:
            raise ConfigError(f"-params {key}: {error}") from error
    return params


def valid_keys(algo: str) -> list[str]:
    """Config keys accepted for a method: the special keys plus the algorithm's constructor arguments."""
    excluded = {"policy", "env", "_init_setup_model", "args", "kwargs"}
    return sorted({*CONFIG_KEYS, *(name for name in _constructor_parameters(algo) if name not in excluded)})


def _constructor_parameters(algo: str) -> dict[str, inspect.Parameter]:
    """Constructor parameters of a method's algorithm class (every class spells out its full signature)."""
    return dict(inspect.signature(ALGOS[algo]).parameters)


# Keys whose value is a dict, or a string evaluated to one (rl-zoo's ``policy_kwargs`` convention).
_DICT_KEYS = ("policy_kwargs", "env_kwargs", "intrinsic_kwargs")


def _type_ok(value: Any, reference: Any) -> bool:
    if reference is None or value is None:
        return True
    if isinstance(reference, bool):
        return isinstance(value, bool)
    if isinstance(reference, (int, float)):
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if isinstance(reference, str):
        return isinstance(value, str)
    if isinstance(reference, (list, tuple)):
        return isinstance(value, (list, tuple))
    if isinstance(reference, dict):
        return isinstance(value, dict)
    return True


def _matches(value: Any, annotation: Any) -> bool:
    """Whether a YAML value fits a constructor annotation (int accepted for float; unknown annotations accept)."""
    if isinstance(annotation, str):  # postponed annotations, e.g. "float | None"
        options = [option.strip() for option in annotation.split("|")]
    elif isinstance(annotation, (type, types.UnionType)):
        members = typing.get_args(annotation) if isinstance(annotation, types.UnionType) else (annotation,)
        options = ["None" if member is type(None) else getattr(member, "__name__", "?") for member in members]
    else:
        return True
    checks = {"float": (int, float), "int": (int,), "bool": (bool,), "str": (str,), "None": (type(None),)}
    if any(option not in checks for option in options):
        return True  # Schedules, classes, dicts...: left to the algorithm
    if isinstance(value, bool) and "bool" not in options:
        return False
    return any(isinstance(value, checks[option]) for option in options)


def _annotations(algo: str) -> dict[str, Any]:
    """Constructor annotations of a method's algorithm class."""
    return {
        name: parameter.annotation
        for name, parameter in _constructor_parameters(algo).items()
        if parameter.annotation is not inspect.Parameter.empty
    }


def check_hyperparams(algo: str, hyperparams: dict[str, Any], overrides: dict[str, Any]) -> None:
    """Unknown keys and values of the wrong type raise a :class:`~sb3_saeir.config.ConfigError` naming the valid choices."""
    keys = valid_keys(algo)
    for key in [*hyperparams, *overrides]:
        if key not in keys:
            raise ConfigError(f"unknown config key {key!r} for {algo}; valid keys: {', '.join(keys)}.")
    annotations = _annotations(algo)
    for key, value in hyperparams.items():  # the file's own values: a string where the algorithm takes a bool...
        if key not in _DICT_KEYS and key not in overrides and not _matches(value, annotations.get(key)):
            raise ConfigError(f"config entry {key}={value!r} has type {type(value).__name__}, expected {annotations[key]}.")
    for key, value in overrides.items():
        if key in _DICT_KEYS:
            if value is not None and not isinstance(value, (dict, str)):
                raise ConfigError(f'{key} must be a dict or a string like "dict(key=value)", got {value!r}.')
            continue
        reference = hyperparams.get(key)
        if reference is not None and not _type_ok(value, reference):
            expected = f"{type(reference).__name__} (like the configured {reference!r})"
        elif reference is None and not _matches(value, annotations.get(key)):
            expected = str(annotations[key])
        else:
            continue
        raise ConfigError(f"hyperparameter {key}={value!r} has type {type(value).__name__}, expected {expected}.")
    check_n_envs(overrides.get("n_envs", hyperparams.get("n_envs")))
    n_timesteps = overrides.get("n_timesteps", hyperparams.get("n_timesteps"))
    if n_timesteps is not None and (
        isinstance(n_timesteps, bool) or not isinstance(n_timesteps, (int, float)) or n_timesteps < 1
    ):
        raise ConfigError(f"n_timesteps (-n, agent-steps) must be a positive number, got {n_timesteps!r}.")
    num_cpus = overrides.get("num_cpus", hyperparams.get("num_cpus", 0))
    if isinstance(num_cpus, bool) or not isinstance(num_cpus, int) or num_cpus < 0:
        raise ConfigError(f"num_cpus (env worker processes) must be an integer >= 0, got {num_cpus!r}.")


def check_params_against_flags(params: dict[str, Any], flags: dict[str, tuple[str, Any]]) -> None:
    """Refuse a ``-params`` key that a flag of the command sets too, to another value (the flag won without a word,
    and the benchmark's record kept the ``-params`` value, which did not train).

    :param params: the ``-params`` overrides
    :param flags: config key -> (the flag that sets it, its value; ``None``: not given)
    :raises ~sb3_saeir.config.ConfigError: naming both
    """
    for key, (flag, value) in flags.items():
        if value is not None and key in params and params[key] != value:
            raise ConfigError(f"-params {key}:{params[key]!r} and {flag} {value} disagree: give it once.")


def check_n_envs(n_envs: Any) -> None:
    """Refuse an ``n_envs`` (number of games) that is not a positive integer, from a config file or ``-params``
    (``None``: not given, accepted).

    :param n_envs: the value
    :raises ~sb3_saeir.config.ConfigError: naming ``n_envs``
    """
    if n_envs is not None and (isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1):
        raise ConfigError(f"n_envs (number of games) must be a positive integer, got {n_envs!r}; e.g. n_envs: 8.")


def check_count(owner: str, name: str, value: Any, low: int) -> int:
    """A count of an object's (``Experiment``'s ``n_games``, ``num_cpus``) as an int ``>= low``; a fractional, boolean
    or string value is refused (``int()`` would truncate it), a whole float taken.

    :param owner: the object, for the message
    :param name: the count's name
    :param value: its value
    :param low: the smallest count
    :raises ValueError: naming the count
    """
    whole = isinstance(value, int) or (isinstance(value, float) and value.is_integer())
    if isinstance(value, bool) or not whole or value < low:
        raise ValueError(f"{owner}: {name} must be an integer >= {low}, got {value!r}.")
    return int(value)


def config_dir() -> Path:
    """Folder of the packaged configs, ``sb3_saeir/zoo_configs/`` (the repository's ``zoo_configs/`` links to it)."""
    return Path(__file__).parent / "zoo_configs"


def config_path(algo: str) -> Path:
    """Path of the packaged config of a method."""
    check_algo(algo)
    return config_dir() / f"{algo}.yml"


def load_hyperparams(algo: str, task: str, conf_file: str | os.PathLike | None = None) -> dict[str, Any]:
    """The entry of ``task`` in a config file (default: the packaged ``zoo_configs/<algo>.yml``).

    :raises KeyError: when the file has no entry for the task (the message lists the tasks it has)
    """
    path = Path(conf_file) if conf_file is not None else config_path(algo)
    with open(path) as file:
        try:
            entries = load_yaml(file) or {}
        except yaml.YAMLError as error:
            where = getattr(error, "problem_mark", None)
            line = f" (line {where.line + 1})" if where is not None else ""
            raise ConfigError(f"{path} is not valid YAML{line}: {getattr(error, 'problem', error)}.") from error
        except ConfigError as error:
            raise ConfigError(f"{path}: {error}") from error
    if not isinstance(entries, dict) or not all(isinstance(entry, dict) for entry in entries.values()):
        raise ConfigError(f"{path} must map task ids to dicts of hyperparameters (rl-zoo's layout).")
    if not entries:
        raise ConfigError(f"{path} is empty: it must map task ids to dicts of hyperparameters (rl-zoo's layout).")
    if task not in entries:
        raise KeyError(f"{path} has no entry for task {task!r}. Entries: {', '.join(sorted(entries))}.")
    return dict(entries[task])


def _resolve(dotted: str) -> Any:
    """The object ``module.Name`` names; a :class:`~sb3_saeir.config.ConfigError` naming the config's ``callback`` when
    it does not import."""
    module_name, _, name = dotted.rpartition(".")
    try:
        return getattr(importlib.import_module(module_name), name)
    except (ImportError, AttributeError, ValueError) as error:
        raise ConfigError(f"callback {dotted!r} does not import ({type(error).__name__}: {error}).") from error


def build_callbacks(spec: Any) -> list[BaseCallback]:
    """Instantiate rl-zoo style callback entries (``"module.Class"``, ``{"module.Class": {kwargs}}`` or a list).

    :raises ~sb3_saeir.config.ConfigError: when an entry has another form, does not import, or its class refuses its arguments
    """
    if spec is None:
        return []
    callbacks = []
    for entry in spec if isinstance(spec, list) else [spec]:
        kwargs: dict[str, Any] | None
        if isinstance(entry, str):
            name, kwargs = entry, {}
        elif isinstance(entry, dict) and len(entry) == 1 and isinstance(next(iter(entry.values())), (dict, type(None))):
            ((name, kwargs),) = entry.items()
        else:
            raise ConfigError(f'callback entry {entry!r} is not "module.Class" or {{"module.Class": {{kwargs}}}}.')
        try:
            callbacks.append(_resolve(name)(**(kwargs or {})))
        except (TypeError, ValueError) as error:
            if isinstance(error, ConfigError):
                raise
            raise ConfigError(f"callback {name!r}: {error}") from error
    return callbacks


def parse_policy_kwargs(policy_kwargs: Any) -> dict[str, Any]:
    """A dict, or a string evaluated with ``nn`` (torch.nn) in scope, as rl-zoo does.

    Also used for ``env_kwargs`` and ``intrinsic_kwargs``, so that ``-params "env_kwargs:dict(N=3, reward='reach')"``
    and ``-params "intrinsic_kwargs:dict(variant='paper')"`` work like rl-zoo's ``policy_kwargs``.
    """
    if policy_kwargs is None:
        return {}
    if isinstance(policy_kwargs, str):
        try:
            value = eval(policy_kwargs, {"nn": nn, "dict": dict})
        except Exception as error:  # the user's expression: any failure is a bad config value
            raise ConfigError(f"cannot evaluate {policy_kwargs!r}: {type(error).__name__}: {error}.") from error
        if not isinstance(value, dict):
            raise ConfigError(f"{policy_kwargs!r} evaluates to {type(value).__name__}, expected a dict.")
        return value
    if not isinstance(policy_kwargs, dict):
        raise ConfigError(f'expected a dict or a string like "dict(key=value)", got {policy_kwargs!r}.')
    return dict(policy_kwargs)


def algorithm_kwargs(params: dict[str, Any], n_games: int, env: VecEnv) -> dict[str, Any]:
    """A config entry's arguments of the algorithm class (every key but :data:`CONFIG_KEYS`), for a model on ``env``
    with ``n_games`` games: ``intrinsic_kwargs`` parsed, and a ``batch_size`` that is the config's whole rollout kept
    the whole rollout with ``n_games`` games.

    :param params: the config entry
    :param n_games: the games of the model's env
    :param env: the model's multi-agent vec env (``n_games`` games)
    """
    kwargs = {key: value for key, value in params.items() if key not in CONFIG_KEYS}
    if "intrinsic_kwargs" in kwargs:
        kwargs["intrinsic_kwargs"] = parse_policy_kwargs(kwargs["intrinsic_kwargs"])
    config_games = params.get("n_envs", n_games)
    n_agents = env.num_envs // n_games
    if "batch_size" in kwargs and kwargs["batch_size"] == params.get("n_steps", 0) * config_games * n_agents:
        kwargs["batch_size"] = params["n_steps"] * env.num_envs  # the whole rollout with this game count
    return kwargs


def loaded_network(model: BaseAlgorithm, path: str | Path, requested: Any, configured: Any) -> str | None:
    """``-i``: a loaded model trains the network it was saved with (SB3's ``load`` drops other ``policy_kwargs``
    without a word). Refuse a ``-params policy_kwargs`` that asks for another network; return the loaded network's
    ``policy_kwargs`` as a config writes them when the config's describe another network (the run's record then
    says what trains), else ``None``.

    :param model: the loaded model
    :param path: where it was loaded from (``-i``)
    :param requested: the command's ``-params policy_kwargs`` (``None``: not given)
    :param configured: the config entry's ``policy_kwargs``
    :raises ~sb3_saeir.config.ConfigError: naming the settings that cannot apply
    """
    in_config = parse_policy_kwargs(configured)
    asked = parse_policy_kwargs(requested) if requested is not None else {}
    saved = {
        key: value
        for key, value in (getattr(model, "policy_kwargs", {}) or {}).items()
        if key not in ALGORITHM_POLICY_KWARGS or key in in_config or key in asked
    }  # as a config writes them: without what the algorithm sets itself
    defaults = {
        name: parameter.default
        for name, parameter in inspect.signature(type(model.policy).__init__).parameters.items()
        if parameter.default is not inspect.Parameter.empty
    }

    def differing(kwargs: dict[str, Any], keys: set[str]) -> list[str]:
        """The keys of ``keys`` whose value (a policy default where not given) differs from the loaded network's."""
        return [key for key in sorted(keys) if kwargs.get(key, defaults.get(key)) != saved.get(key, defaults.get(key))]

    keys = differing(asked, set(asked))
    if keys:
        wanted = ", ".join(f"{key}={kwarg_text(asked[key])}" for key in keys)
        has = ", ".join(f"{key}={kwarg_text(saved.get(key, defaults.get(key)))}" for key in keys)
        raise ConfigError(
            f"-i {path}: -params policy_kwargs {wanted} cannot apply to the loaded model, whose network has {has}: a "
            "loaded model trains the network it was saved with. Drop the policy_kwargs override, or start a new run "
            "without -i."
        )
    if differing(in_config, set(in_config) | set(saved)):
        return "dict(" + ", ".join(f"{key}={kwarg_text(value)}" for key, value in sorted(saved.items())) + ")"
    return None


def kwarg_text(value: Any) -> str:
    """A policy keyword's value as a config writes it (``nn.Tanh`` for a torch module class)."""
    if isinstance(value, type) and value.__module__.startswith("torch.nn"):
        return f"nn.{value.__name__}"
    return repr(value)


# ---------------------------------------------------------------------------------------------------- saved models
def _policy_name(policy: Any) -> str:
    return policy if isinstance(policy, str) else getattr(policy, "__name__", str(policy))


def saved_model_kind(path: str | Path) -> tuple[str, str | None] | None:
    """The policy class and ``intrinsic_reward`` of a saved model, read from the zip's ``data`` (no weights loaded);
    ``None`` when they cannot be read (not an SB3 zip: the load reports it).

    SB3's zip does not record the algorithm class; the policy class and the intrinsic reward tell the package's
    methods apart (``sn_mappo`` has ``SNMAPPOPolicy``, ``mshg_only`` ``MSHGPolicy`` without a bonus, ...).
    """
    data = read_zip_data(path)
    policy = saved_policy_class(data) if data is not None else None
    if data is None or policy is None:  # any unreadable zip: SB3's load gives its own message
        return None
    return _policy_name(policy), data.get("intrinsic_reward")


def method_kind(algo: str, hyperparams: dict[str, Any]) -> tuple[str, str | None]:
    """The policy class and ``intrinsic_reward`` a method's config entry trains (see :func:`saved_model_kind`)."""
    algo_class = ALGOS[algo]
    policy = hyperparams.get("policy", "MlpPolicy")
    policy_class = algo_class.policy_aliases.get(policy, policy) if isinstance(policy, str) else policy
    default = inspect.signature(algo_class).parameters.get("intrinsic_reward")
    intrinsic = hyperparams.get("intrinsic_reward", default.default if default is not None else None)
    return _policy_name(policy_class), intrinsic


def model_method_mismatch(path: str | Path, algo: str, task: str, hyperparams: dict[str, Any]) -> str:
    """Why the model saved at ``path`` is not a model of method ``algo`` (its config entry ``hyperparams``), naming
    the model's policy class and the methods it fits; ``""`` when it fits (or cannot be read).

    :param path: the model zip
    :param algo: the method of the command
    :param task: the task (to look up the other methods' packaged configs)
    :param hyperparams: ``algo``'s config entry
    """
    saved = saved_model_kind(path)
    expected = method_kind(algo, hyperparams)
    if saved is None or saved == expected:
        return ""
    fits = []
    for other in sorted(ALGOS):
        try:
            if method_kind(other, load_hyperparams(other, task)) == saved:
                fits.append(other)
        except (KeyError, OSError, ValueError):
            continue
    policy, intrinsic = saved
    hint = f"a model of {', '.join(fits)}; use --algo {fits[0]}" if fits else "a model of no packaged method"
    return (
        f"{path} is a model with {policy} and intrinsic_reward={intrinsic!r} ({hint}), not one of {algo} "
        f"({expected[0]}, intrinsic_reward={expected[1]!r})."
    )


@dataclass(frozen=True)
class ModelSettings:
    """What a config entry builds (or loads) a model with, on a given env (:func:`model_settings`).

    :param policy: the ``policy`` (an alias such as ``"MSHGPolicy"``, or a class)
    :param policy_kwargs: the ``policy_kwargs``, parsed
    :param algorithm_kwargs: the algorithm class's arguments (:func:`algorithm_kwargs`)
    :param callbacks: the ``callback`` entries, built (passed to ``learn``)
    :param resolved: the entry as the model trains it: its games as ``n_envs``, its ``batch_size`` for them
    """

    policy: Any
    policy_kwargs: dict[str, Any]
    algorithm_kwargs: dict[str, Any]
    callbacks: list[BaseCallback]
    resolved: dict[str, Any]


def model_settings(params: dict[str, Any], n_games: int, env: VecEnv) -> ModelSettings:
    """Everything a config entry says about a model on ``env`` with ``n_games`` games, read at once.

    :param params: the config entry
    :param n_games: the games of the model's env
    :param env: the model's multi-agent vec env
    """
    kwargs = algorithm_kwargs(params, n_games, env)
    resolved = {**params, "n_envs": n_games}
    if "batch_size" in kwargs:
        resolved["batch_size"] = kwargs["batch_size"]
    policy_kwargs = parse_policy_kwargs(params.get("policy_kwargs"))
    callbacks = build_callbacks(params.get("callback"))
    return ModelSettings(params.get("policy", "MlpPolicy"), policy_kwargs, kwargs, callbacks, resolved)
