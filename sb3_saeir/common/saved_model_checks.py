"""Checks of saved models: the file given to ``load`` (no file, a folder, another library's model, a zip SB3 cannot
read back or whose network ``custom_objects`` rebuild otherwise) and the parameters given to ``set_parameters`` (another
kind of network, entries missing or unknown), each refused in one line that names the file or argument and the fix
(``docs/guide/algorithms.md``). The constructor's checks are in :mod:`sb3_saeir.common.checks`.
"""

from __future__ import annotations

import contextlib
import json
import os
import pathlib
import pickle
import warnings
import zipfile
from collections.abc import Iterable, Iterator
from typing import Any

import torch as th
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.common.checks import check_n_agents
from sb3_saeir.common.policies import MultiAgentActorCriticPolicy
from sb3_saeir.common.run_state import read_zip_data, saved_policy_class
from sb3_saeir.common.utils import PACKAGE_VERSION, user_stacklevel


# ------------------------------------------------------------------------------------------------ loading
def check_load_arguments(algo_name: str, path: Any, custom_objects: dict[str, Any] | None) -> None:
    """Refuse, before SB3's ``load`` reads anything: a path that is no file (SB3 named ``<path>.zip``, the second
    name it tries, or failed on a folder) and a ``compile`` in ``custom_objects`` (SB3 replaces only what the zip
    holds, and ``compile`` is not saved: it was ignored).

    :param algo_name: class name for the message
    :param path: the ``path`` argument of ``load`` (a file object passes)
    :param custom_objects: the ``custom_objects`` argument of ``load``
    :raises FileNotFoundError: for a path where there is no file
    :raises IsADirectoryError: for a folder
    :raises ValueError: for ``compile`` in ``custom_objects``
    """
    if "compile" in (custom_objects or {}):
        raise ValueError(
            f"{algo_name}.load: custom_objects 'compile' is not used (compile is not saved with a model); pass it as "
            f"{algo_name}.load(path, compile=...)."
        )
    if not isinstance(path, (str, os.PathLike)):
        return
    target = pathlib.Path(path)
    if target.is_dir():
        raise IsADirectoryError(
            f"{algo_name}.load: {str(path)!r} is a folder, not a model zip; give the path of a zip file, such as "
            f"{str(target / 'model.zip')!r}."
        )
    if not target.exists() and not pathlib.Path(f"{path}.zip").exists():  # SB3 reads <path>, else <path>.zip
        raise FileNotFoundError(f"{algo_name}.load: no such file {str(path)!r}.")


def saved_data(path: Any) -> dict[str, Any] | None:
    """The ``data`` entry of an SB3 model zip as JSON, read without loading the model (``None`` when it cannot be
    read: SB3's ``load`` then names the damage). A file object is read and put back where it was.

    :param path: the ``path`` argument of ``load``: a path (``<path>.zip`` when ``<path>`` is no file, as SB3 reads
        it) or a binary file object
    """
    if isinstance(path, (str, os.PathLike)):
        source: Any = path if pathlib.Path(path).is_file() else pathlib.Path(f"{path}.zip")
        position = None
    else:
        try:
            source, position = path, path.tell()
        except (AttributeError, OSError):  # a file object that cannot go back: left to SB3
            return None
    try:
        return read_zip_data(source)  # None for a damaged or foreign file: SB3's load names it
    finally:
        if position is not None:
            path.seek(position)


def check_saved_model(algo_name: str, path: Any, data: dict[str, Any], env: Any) -> None:
    """Refuse a zip that another library saved (its policy class is not a
    :class:`~sb3_saeir.common.policies.MultiAgentActorCriticPolicy`: SB3 failed on the spaces, or on the missing
    ``n_agents``), and an env of another number of agents per game than the model's (checked as ``set_env`` does,
    before SB3's comparison of the observation spaces).

    :param algo_name: class name for the message
    :param path: the ``path`` argument of ``load``
    :param data: the zip's ``data`` (:func:`saved_data`)
    :param env: the ``env`` argument of ``load``
    """
    foreign = _foreign_policy(data)
    if foreign is not None:
        name, library = foreign
        raise ValueError(
            f"{algo_name}.load: {str(path)!r} is a model of another library (its policy class is {name}), not an "
            f"sb3-saeir model; load it with that library's algorithm class, e.g. {library}'s PPO.load."
        )
    n_agents = data.get("n_agents")
    if isinstance(env, VecEnv) and isinstance(n_agents, int) and not isinstance(n_agents, bool):
        check_n_agents(algo_name, env, n_agents)


def warn_other_version(algo_name: str, path: Any, data: dict[str, Any] | None) -> None:
    """One warning line when the model was saved by another sb3-saeir version (``save`` records it in the zip's
    ``data``); a model saved before the version was recorded, or by another library, loads without one.

    :param algo_name: class name for the message
    :param path: the ``path`` argument of ``load``
    :param data: the zip's ``data`` (:func:`saved_data`), or ``None``
    """
    saved_version = (data or {}).get("sb3_saeir_version")
    if isinstance(saved_version, str) and saved_version != PACKAGE_VERSION:
        warnings.warn(
            f"{algo_name}.load: {path} was saved by sb3-saeir {saved_version}; this is {PACKAGE_VERSION}. It loads; "
            "check the CHANGELOG before comparing its results with this version's.",
            UserWarning,
            stacklevel=user_stacklevel(),
        )


def _foreign_policy(data: dict[str, Any]) -> tuple[str, str] | None:
    """The name of the policy class a zip's ``data`` holds (``policy_class``, as SB3 serialises a class) and its
    library (the top package of its module) when it is another library's: from a module outside the package and not a
    :class:`~sb3_saeir.common.policies.MultiAgentActorCriticPolicy` (a user's subclass is the package's); ``None``
    otherwise, or when the entry is not one SB3 writes.

    :param data: the zip's ``data`` (:func:`~sb3_saeir.common.run_state.read_zip_data`)
    """
    entry = data.get("policy_class")
    module = entry.get("__module__") if isinstance(entry, dict) else None
    if not isinstance(module, str) or module.split(".")[0] == "sb3_saeir":
        return None
    library = module.split(".")[0]
    policy_class = saved_policy_class(data)
    if policy_class is None:  # its module is not installed here, or the entry is damaged: named by its module
        return f"a class of {module}", library
    if isinstance(policy_class, type) and issubclass(policy_class, MultiAgentActorCriticPolicy):
        return None
    return f"{module}.{getattr(policy_class, '__qualname__', policy_class)}", library


# ------------------------------------------------------------------------------------------------ saved networks
# (GRU in the actor, GRUs in the critics) -> how the messages name the network, and the policy_kwargs that build it
_NETWORK_KINDS: dict[tuple[bool, bool], tuple[str, str]] = {
    (True, True): ("recurrent", "recurrent=True"),
    (False, False): ("feed-forward", "recurrent=False"),
    (False, True): ("recurrent in the critics only", "recurrent=True, recurrent_actor=False"),
    (True, False): ("recurrent in the actor only", "recurrent=False, recurrent_actor=True"),
}


class NetworkMismatchError(ValueError):
    """Saved parameters of a recurrent network given to a feed-forward model, or the reverse
    (:func:`check_network_kind`); :func:`model_zip_errors` says which ``load`` argument caused it.

    :param message: the one line
    :param saved: (GRU in the actor, GRUs in the critics) of the saved parameters
    :param built: the same of the model's network
    """

    def __init__(self, message: str, saved: tuple[bool, bool], built: tuple[bool, bool]) -> None:
        super().__init__(message)
        self.saved = saved
        self.built = built


def network_recurrence(state_dict_keys: Iterable[str]) -> tuple[bool, bool]:
    """(GRU in the actor, GRUs in the critics) of a policy, read from the keys of its state dict.

    :param state_dict_keys: the keys of a :class:`~sb3_saeir.common.policies.MultiAgentActorCriticPolicy`'s state dict
    """
    keys = list(state_dict_keys)
    actor = any(key.startswith("actor.gru.") for key in keys)
    critics = any(key.startswith("critics.") and ".gru." in key for key in keys)
    return actor, critics


def describe_network(recurrence: tuple[bool, bool]) -> str:
    """``"recurrent (recurrent=True)"``, ``"feed-forward (recurrent=False)"``, ...: a network's kind and the
    ``policy_kwargs`` that build it.

    :param recurrence: (GRU in the actor, GRUs in the critics), as :func:`network_recurrence` gives it
    """
    kind, settings = _NETWORK_KINDS[recurrence]
    return f"{kind} ({settings})"


def check_network_kind(owner: str, saved_policy: Iterable[str], policy: MultiAgentActorCriticPolicy) -> None:
    """Refuse saved policy parameters of a recurrent network for a feed-forward model, or the reverse, before any is
    set (torch's ``load_state_dict`` error listed every GRU key, over many lines).

    :param owner: who sets them, for the message (``"MAPPO.set_parameters"``)
    :param saved_policy: the saved policy's state dict (or its keys)
    :param policy: the model's policy
    :raises NetworkMismatchError: one line naming both kinds and the fix
    """
    saved, built = network_recurrence(saved_policy), network_recurrence(policy.state_dict())
    if saved == built:
        return
    (saved_kind, saved_settings), (built_kind, built_settings) = _NETWORK_KINDS[saved], _NETWORK_KINDS[built]
    raise NetworkMismatchError(
        f"{owner}: the parameters are of a {saved_kind} network ({saved_settings}), this model's network is "
        f"{built_kind} ({built_settings}); set them on a model built with policy_kwargs {saved_settings} "
        f"({owner.split('.')[0]}.load(path) builds the saved network).",
        saved,
        built,
    )


class ParameterNamesError(ValueError):
    """Parameters given with ``exact_match`` whose entries are not the model's (:func:`check_parameter_names`);
    :func:`model_zip_errors` says which ``load`` argument caused it.

    :param message: the one line
    :param differences: the entries missing and unexpected, for ``load``'s message
    """

    def __init__(self, message: str, differences: str) -> None:
        super().__init__(message)
        self.differences = differences


def check_parameter_names(owner: str, params: dict[str, Any], model: Any) -> None:
    """For ``set_parameters(..., exact_match=True)``: refuse parameters that are not every one of the model's, or
    that the model does not have, before any is set (torch's ``load_state_dict`` set the tensors it found, then raised
    over two lines). Optimizer states are left to torch (it checks them before setting any).

    :param owner: who sets them, for the message (``"MAPPO.set_parameters"``)
    :param params: object name (``"policy"``, ``"policy.optimizer"``) -> state dict, as ``get_parameters`` returns them
    :param model: the model whose parameters are set
    :raises ValueError: one line naming a few missing and unexpected entries and the fix
    """
    from stable_baselines3.common.save_util import recursive_getattr

    expected = list(model._get_torch_save_params()[0])
    missing = [name for name in expected if name not in params]
    unexpected = [name for name in params if name not in expected]
    for name in (name for name in expected if name in params):
        target, given = recursive_getattr(model, name), params[name]
        if isinstance(target, th.nn.Module) and isinstance(given, dict):
            own = target.state_dict()
            missing += [f"{name}[{key!r}]" for key in own if key not in given]
            unexpected += [f"{name}[{key!r}]" for key in given if key not in own]
    if missing or unexpected:
        found = [f"{what} {_a_few(names)}" for what, names in (("missing", missing), ("unexpected", unexpected)) if names]
        raise ParameterNamesError(
            f"{owner}: the parameters are not this model's ({'; '.join(found)}); nothing was set. Pass every entry of "
            "get_parameters(), or exact_match=False to set only those that match.",
            "; ".join(found),
        )


def _a_few(names: list[str], shown: int = 3) -> str:
    """The first ``shown`` names, and how many more."""
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    return ", ".join(names[:shown]) + more


@contextlib.contextmanager
def model_zip_errors(algo_name: str, path: Any, custom_objects: dict[str, Any] | None = None) -> Iterator[None]:
    """Around SB3's ``load``: the errors it raises for a file that is not a complete model zip (truncated or edited)
    become one ``ValueError`` line naming the file; the package's own ``ValueError`` (n_agents, ranges) pass through.
    Where ``custom_objects`` replace the saved ``policy_kwargs`` and the network they build does not take the saved
    parameters, the line names the override as the cause, not the file.

    :param algo_name: class name for the message
    :param path: the ``path`` argument of ``load``
    :param custom_objects: the ``custom_objects`` argument of ``load``
    """
    override = (custom_objects or {}).get("policy_kwargs", _NO_OVERRIDE)
    try:
        yield
    except NetworkMismatchError as error:
        if override is _NO_OVERRIDE:  # the zip's own policy_kwargs and parameters disagree: an edited zip
            raise _incomplete_model_error(algo_name, path, error) from None
        raise _override_kind_error(algo_name, path, override, error) from None
    except ParameterNamesError as error:
        if override is _NO_OVERRIDE:
            raise _incomplete_model_error(algo_name, path, error) from None
        raise _override_error(algo_name, path, override, error.differences) from None
    except (zipfile.BadZipFile, EOFError, pickle.UnpicklingError, KeyError, RuntimeError, AssertionError) as error:
        if override is not _NO_OVERRIDE and isinstance(error, RuntimeError) and "loading state_dict" in str(error):
            lines = [line.strip() for line in str(error).splitlines() if line.strip()]
            detail = lines[1] if len(lines) > 1 else lines[0]  # torch's first mismatch
            raise _override_error(algo_name, path, override, detail.rstrip(". ")) from None
        raise _incomplete_model_error(algo_name, path, error) from None
    except ValueError as error:
        # SB3's own ValueErrors for a damaged zip
        if isinstance(error, json.JSONDecodeError) or "Names of parameters do not match" in str(error):
            raise _incomplete_model_error(algo_name, path, error) from None
        raise


_NO_OVERRIDE = object()  # model_zip_errors: no policy_kwargs in custom_objects


def _incomplete_model_error(algo_name: str, path: Any, error: BaseException) -> ValueError:
    """One line for a model file that SB3 could not read back."""
    detail = str(error).splitlines()[0] if str(error) else "no detail"
    return ValueError(
        f"{algo_name}.load: {str(path)!r} is not a complete sb3-saeir model zip ({type(error).__name__}: {detail}); "
        "save the model again with model.save."
    )


def _override_kind_error(algo_name: str, path: Any, override: Any, error: NetworkMismatchError) -> ValueError:
    """One line for ``custom_objects={"policy_kwargs": ...}`` that build a recurrent network for the saved parameters
    of a feed-forward one, or the reverse."""
    items = override.items() if isinstance(override, dict) else ()
    given = {key: value for key, value in items if key in ("recurrent", "recurrent_actor")}
    if given:
        what = ", ".join(f"{key}={value!r}" for key, value in given.items())
    else:
        what = f"without recurrent (so {_NETWORK_KINDS[error.built][1]}, the default)"
    return ValueError(
        f"{algo_name}.load: custom_objects policy_kwargs {what} does not fit {str(path)!r}, whose network is "
        f"{describe_network(error.saved)}; drop the policy_kwargs override, or give {_NETWORK_KINDS[error.saved][1]} "
        "in it (custom_objects replace the saved policy_kwargs whole)."
    )


def _override_error(algo_name: str, path: Any, override: Any, detail: str) -> ValueError:
    """One line for ``custom_objects={"policy_kwargs": ...}`` that build another network than the saved one (other
    sizes, other entries), ``detail`` naming the first differences."""
    return ValueError(
        f"{algo_name}.load: custom_objects policy_kwargs {override!r} do not fit the network saved in {str(path)!r} "
        f"({detail}); drop the policy_kwargs override, or repeat the saved policy_kwargs in it "
        "(custom_objects replace them whole)."
    )
