"""Optional ``torch.compile`` of the networks: the algorithms' ``compile`` switch (``docs/guide/performance.md``,
"Compiled networks").

With ``compile=True`` the policy runs the forward of the actor's trunk and of every critic through ``torch.compile``
(the inductor backend: on the CPU it generates C++ kernels, so it needs a C++ compiler), in the rollout's forward
passes and in the update (whose backward AOTAutograd compiles with it). The modules are not wrapped, so the saved
state's keys do not change. Inside compiled code the GRUs run as a step loop the compiler can fuse
(:meth:`~sb3_saeir.common.torch_layers.GRULayer.forward`), and the critics' Gumbel draws are made outside it, from the
global generator as in eager mode. The batch dimensions are marked dynamic, so a new number of blocks (the groups of a
minibatch by valid length, the last minibatch, a subset of games) reuses the compiled code; each network gets one
graph per chunk length and grad mode (the rollout's one step without gradients, the update's chunk lengths).
"""

from __future__ import annotations

import shutil
import warnings
from collections.abc import Callable
from typing import Any

import torch as th

# torch.compile's default recompile limit (8 per code object) is shared by the critics of one class (the three
# HypergraphScaleCritics run the same forward code): each network needs about three entries (rollout step, chunk lengths)
RECOMPILE_LIMIT = 64


def find_cpp_compiler() -> str | None:
    """The C++ compiler the inductor backend would use on the CPU (its ``cpp.cxx`` candidates, looked up on ``PATH``
    now: not cached), or ``None`` when there is none."""
    from torch._inductor import config as inductor_config

    configured = inductor_config.cpp.cxx
    candidates = configured if isinstance(configured, (list, tuple)) else (configured,)
    for name in candidates:
        if name is None:
            continue
        path = shutil.which(name)
        if path is not None:
            return path
    return None


def compile_obstacle(backend: str, device: th.device) -> str | None:
    """Why ``backend`` cannot compile for ``device`` here, in a few words, or ``None`` when it can.

    :param backend: a ``torch.compile`` backend name
    :param device: the policy's device
    """
    if backend != "inductor":
        return None
    if device.type == "cpu" and find_cpp_compiler() is None:
        return "no C++ compiler was found (the inductor backend needs g++ on PATH on the CPU)"
    if device.type == "cuda":
        from torch.utils._triton import has_triton

        if not has_triton():
            return "triton is not installed (the inductor backend needs it on CUDA)"
    return None


# torch's debugging backends a user may pick to tell a compiler fault from a model fault (torch's "torch.compile
# troubleshooting" page): listed with the backends torch lists by default. Its other debug and experimental backends
# (the minifiers', the *_TESTING_ONLY ones, which raise on purpose, AOTAutograd's partition variants) are accepted but
# not listed.
DEBUG_BACKENDS = ("eager", "aot_eager")


def listed_backends() -> list[str]:
    """The ``torch.compile`` backends the ``compile`` refusal names: those ``torch._dynamo.list_backends()`` lists
    (it leaves out torch's debug and experimental ones; a backend registered without tags is listed) and
    :data:`DEBUG_BACKENDS`, sorted."""
    return sorted({*th._dynamo.list_backends(), *DEBUG_BACKENDS})


def check_compile_setting(owner: str, setting: Any) -> None:
    """Refuse a ``compile`` value that is not ``True``, ``False`` or a ``torch.compile`` backend name, in one line.

    Every backend torch knows is accepted (``torch._dynamo.list_backends(exclude_tags=())``); the message lists those
    of :func:`listed_backends` only.

    :param owner: class name for the message
    :param setting: the ``compile`` argument
    """
    if isinstance(setting, bool):
        return
    if not isinstance(setting, str) or setting not in th._dynamo.list_backends(exclude_tags=()):
        raise ValueError(
            f"{owner}: compile must be True, False or a torch.compile backend name ({', '.join(listed_backends())}), "
            f"got {setting!r}."
        )


def resolve_compile_backend(owner: str, setting: bool | str, device: th.device) -> str | None:
    """The backend the networks are compiled with, or ``None`` for eager; where the backend cannot run here (no C++
    compiler for inductor on the CPU), one warning line says so and the networks run eagerly.

    :param owner: class name for the message
    :param setting: the ``compile`` argument (``True`` is the inductor backend)
    :param device: the policy's device
    """
    check_compile_setting(owner, setting)
    if setting is False:
        return None
    backend = "inductor" if setting is True else str(setting)
    obstacle = compile_obstacle(backend, device)
    if obstacle is not None:
        warnings.warn(f"{owner}: compile={setting!r} but {obstacle}; training goes on without compiling (eager).", UserWarning)
        return None
    return backend


def compile_network(forward: Callable[..., Any], backend: str) -> Callable[..., Any]:
    """``torch.compile`` of one network's forward (a bound method: the module itself is not wrapped, so its
    state-dict keys stay as they are).

    :param forward: the network's ``forward``
    :param backend: the ``torch.compile`` backend
    """
    dynamo_config = th._dynamo.config
    dynamo_config.recompile_limit = max(dynamo_config.recompile_limit, RECOMPILE_LIMIT)
    # the GRU layers read nn.GRU's parameters (they do not call it: GRULayer.step_loop); without this, dynamo stops
    # its graph at any nn.GRU module
    dynamo_config.allow_rnn = True
    return th.compile(forward, backend=backend)


def mark_dynamic(tensor: th.Tensor | None, *dims: int) -> None:
    """Mark batch dimensions of a compiled network's input as dynamic (no recompilation when they change size).

    :param tensor: the input (``None``: nothing to mark)
    :param dims: its batch dimensions
    """
    if tensor is None:
        return
    for dim in dims:
        if tensor.shape[dim] > 1:  # sizes 0 and 1 are always specialised by the compiler
            th._dynamo.maybe_mark_dynamic(tensor, dim)


def compile_counters() -> dict[str, int]:
    """Compilations so far in this process: frames compiled (a frame per network forward, per recompilation) and
    graphs produced, from ``torch._dynamo.utils.counters``."""
    from torch._dynamo.utils import counters

    return {"frames": int(counters["frames"]["ok"]), "graphs": int(counters["stats"]["unique_graphs"])}
