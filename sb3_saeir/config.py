"""rl-zoo style YAML configs and the models built from them: one file per method in ``zoo_configs/``, one entry per
task id.

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
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv
from torch import nn

from sb3_saeir.common.vec_env import make_multiagent_vec_env
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

# Keys of a config entry that are not constructor arguments of the algorithm.
CONFIG_KEYS = ("n_timesteps", "n_envs", "num_cpus", "env_kwargs", "policy", "policy_kwargs", "callback")
# Games of a config entry without ``n_envs``.
DEFAULT_N_GAMES = 8


class ConfigError(ValueError):
    """A bad command line or config: the message names the problem and the valid choices."""


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


def check_n_envs(n_envs: Any) -> None:
    """Refuse an ``n_envs`` (number of games) that is not a positive integer, from a config file or ``-params``
    (``None``: not given, accepted).

    :param n_envs: the value
    :raises ~sb3_saeir.config.ConfigError: naming ``n_envs``
    """
    if n_envs is not None and (isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1):
        raise ConfigError(f"n_envs (number of games) must be a positive integer, got {n_envs!r}; e.g. n_envs: 8.")


def config_dir() -> Path:
    """Folder of the packaged configs, ``sb3_saeir/zoo_configs/`` (the repository's ``zoo_configs/`` links to it)."""
    return Path(__file__).parent / "zoo_configs"


def config_path(algo: str) -> Path:
    """Path of the packaged config of a method."""
    if algo not in ALGOS:
        raise KeyError(f"Unknown algorithm {algo!r}. Valid choices: {', '.join(sorted(ALGOS))}.")
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


def build_model(
    algo: str,
    task: str,
    hyperparams: dict[str, Any] | None = None,
    n_games: int | None = None,
    seed: int | None = None,
    env: VecEnv | None = None,
    **model_kwargs: Any,
) -> tuple[OnPolicyAlgorithm, VecEnv, list[BaseCallback], dict[str, Any]]:
    """Build a method's model on a task from its config entry.

    :param algo: method name (a key of :data:`ALGOS`)
    :param task: task id
    :param hyperparams: the config entry (default: the packaged one)
    :param n_games: override ``n_envs`` (number of games)
    :param seed: seed of model and env
    :param env: use this multi-agent vec env (possibly wrapped) instead of creating one
    :param model_kwargs: extra algorithm arguments (override the config; e.g. ``verbose``, ``tensorboard_log``)
    :return: model, env, the config's callbacks (pass them to ``learn``), and the resolved hyperparameters
    """
    params = dict(load_hyperparams(algo, task) if hyperparams is None else hyperparams)
    resolved = dict(params)
    games = int(n_games if n_games is not None else params.get("n_envs", DEFAULT_N_GAMES))
    resolved["n_envs"] = games
    if env is None:
        num_cpus = int(params.get("num_cpus", 0))
        env_kwargs = parse_policy_kwargs(params.get("env_kwargs"))
        env = make_multiagent_vec_env(task, n_games=games, seed=seed, num_cpus=num_cpus, **env_kwargs)
    algo_kwargs = algorithm_kwargs(params, games, env)
    if "batch_size" in algo_kwargs:
        resolved["batch_size"] = algo_kwargs["batch_size"]
    algo_kwargs.update(model_kwargs)
    policy = params.get("policy", "MlpPolicy")
    policy_kwargs = parse_policy_kwargs(params.get("policy_kwargs"))
    model = ALGOS[algo](policy, env, policy_kwargs=policy_kwargs, seed=seed, **algo_kwargs)
    return model, env, build_callbacks(params.get("callback")), resolved
