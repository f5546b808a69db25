"""Sequentially accumulated entropy intrinsic reward (SAEIR, IJCAI-24), as a pure NumPy function.

Reference: ``docs/method.md``, "The intrinsic reward" (the released code) and the paper's Eqs. 11-15.
"""

import numpy as np

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer
from sb3_saeir.common.registry import register_intrinsic_reward
from sb3_saeir.common.utils import check_bool
from sb3_saeir.intrinsic.base import IntrinsicRewardCallback

# The readings of the bonus (``docs/method.md``, "The intrinsic reward"): the released code, the paper's Eqs. 12-14
# literally, the supplement's Fig. 3.
SAEIR_VARIANTS = ("code", "paper", "supplement")


def check_saeir_variant(variant: str) -> None:
    """Refuse a SAEIR variant that is not one of :data:`SAEIR_VARIANTS`, in one line naming the choices (the one check,
    for :func:`saeir_bonus` and :class:`SAEIRCallback`).

    :param variant: the ``variant`` argument
    """
    if variant not in SAEIR_VARIANTS:
        raise ValueError(f"Unknown SAEIR variant {variant!r}; choose one of {SAEIR_VARIANTS}.")


def saeir_bonus(
    values: np.ndarray,
    variant: str = "code",
    episode_starts: np.ndarray | None = None,
    last_values: np.ndarray | None = None,
    last_dones: np.ndarray | None = None,
) -> np.ndarray:
    r"""
    Unscaled SAEIR bonus of every stored step, computed from the stored critic outputs of one scale.

    The window of a step is the stretch of the rollout that precedes it: by default the whole rollout
    buffer window (the authors' behaviour, dones are ignored), or the current episode when ``episode_starts``
    is given. Everything is computed independently for every trailing index (env, agent, scale, ...).
    The result is **not** multiplied by the intrinsic coefficient :math:`\beta` (0.1 in the released code).

    **variant="code"** (the released code; ``docs/method.md``, "The intrinsic reward"). With
    :math:`p^{(n)}_j = e^{v_j} / \sum_{l<n} e^{v_l}` the softmax over the first :math:`n` window entries and

    .. math::

        H_n = -\sum_{j<n} p^{(n)}_j \log p^{(n)}_j, \qquad H_0 = 0,

        r_t = H_t \, \mathbb{1}[H_t > H_{t+1}],

    i.e. step :math:`t` is rewarded with the entropy of the value-softmax over the *preceding* window steps
    whenever appending :math:`v_t` lowers that entropy. The bootstrap value is never used. It is evaluated in
    :math:`O(T)` with a running log-sum-exp :math:`L_{n+1} = \operatorname{logaddexp}(L_n, v_n)` and the
    grouping identity, which is algebraically equal to :math:`H_n = \log S_n - A_n / S_n` of
    the released code but has no cancellation and no overflow:

    .. math::

        q_n = e^{v_n - L_{n+1}}, \qquad
        H_{n+1} = -q_n \log q_n - (1 - q_n) \log (1 - q_n) + (1 - q_n) H_n .

    Steps 0 and 1 of a window never fire (:math:`H_0 = H_1 = 0`). The code's :math:`10^{-8}` clamps are
    not reproduced; they change the result by less than :math:`10^{-7}` in normal ranges.
    Worked example: values ``[0, 0, 2, 0.5, 3]`` give ``[0, 0, log 2, 0, 0]`` (only ``t=2`` fires,
    :math:`H_2 = \log 2 \approx 0.693 > H_3 \approx 0.666`).

    **variant="paper"** (Eqs. 12-14 read literally). The per-state term of step :math:`t` with a
    window of the first :math:`n` steps is

    .. math::

        p_t(n) = \frac{e^{v_t}}{\sum_{l<n} e^{v_l}}, \qquad \hat e_t(n) = -p_t(n) \log p_t(n),

        r_t = \hat e_t(t+1) \, \mathbb{1}[\hat e_t(t+1) > \hat e_t(t+2)],

    where :math:`\hat e_t(t+1)` ("T", the window ends at :math:`t`) and :math:`\hat e_t(t+2)` ("T+1", the
    window ends at :math:`t+1`). This needs a **one-step look-ahead** :math:`v_{t+1}`: at the last step of
    the rollout ``last_values`` (the bootstrap values) play the role of :math:`v_T`; without them the last
    step gets 0. With ``episode_starts`` the look-ahead never crosses into the next episode: the last step of
    every episode that ends inside the rollout gets 0. ``last_values`` continue the episode of step :math:`T-1`
    unless ``last_dones`` says that step ended it; there the last step gets 0.

    **variant="supplement"** (the reading that reproduces the supplement's Fig. 3; ``docs/method.md``,
    "Supplement variant"). One softmax over the **whole window** (its stored values plus, where it continues the
    episode, the bootstrap value: :math:`T+1` entries), the per-state term of every entry, and a reward at step
    :math:`t` when the next state's term is lower:

    .. math::

        p_t = \frac{e^{v_t}}{\sum_{l \in W} e^{v_l}}, \qquad \hat e_t = -p_t \log p_t, \qquad
        r_t = \hat e_t \, \mathbb{1}[\hat e_t > \hat e_{t+1}], \quad t = 0, \dots, T-1.

    The last step compares with the bootstrap value's term when ``last_values`` are given and ``last_dones`` does
    not mark the end of its episode; otherwise it gets 0 and the bootstrap is not part of the window. With
    ``episode_starts`` every episode inside the rollout is its own window, normalised over its own steps, and its
    last step gets 0. Near-flat values give :math:`\hat e \approx \log(T+1)/(T+1)` on about half of the steps.

    :param values: Stored critic outputs of one scale, time first: shape ``(T, ...)``,
        e.g. ``(T, n_envs, n_agents)`` or ``(T, n_envs, n_agents, n_scales)``.
    :param episode_starts: Optional, 1 where a new episode starts at step ``t``; shape ``(T, ...)`` whose
        axes are aligned from the **left** with ``values`` (missing trailing axes are broadcast, so
        ``(T, n_envs)`` works for ``values`` of shape ``(T, n_envs, n_agents)``). When given, the entropy
        window restarts at those steps. ``None`` (default) = the authors' behaviour: one window for the whole
        rollout, dones ignored.
    :param variant: ``"code"`` (released code), ``"paper"`` (Eqs. 12-14, literal) or ``"supplement"``
        (whole-window softmax, the supplement's Fig. 3).
    :param last_values: Values of the step after the rollout, shape ``values.shape[1:]`` (broadcastable).
        Used by ``"paper"`` and ``"supplement"`` as the look-ahead of the last step; ignored by ``"code"``.
    :param last_dones: Optional, 1 where the last step ended its episode (so ``last_values`` belong to the next
        one), shape ``values.shape[1:]`` aligned from the left like ``episode_starts``. ``None`` = it did not.
    :return: The unscaled bonus, same shape as ``values``; dtype of ``values`` if it is a float dtype,
        float64 otherwise.
    """
    values = np.asarray(values)
    check_saeir_variant(variant)
    if values.ndim == 0:
        raise ValueError("`values` must have a leading time axis, got a 0-d array")
    out_dtype = values.dtype if np.issubdtype(values.dtype, np.floating) else np.float64
    values64 = values.astype(np.float64)
    if values64.shape[0] == 0:
        return np.zeros(values.shape, dtype=out_dtype)
    starts = None if episode_starts is None else _broadcast_starts(episode_starts, values64.shape)
    has_bootstrap = _bootstrap_mask(values64.shape, last_values, last_dones)
    bootstrap = None
    if last_values is not None:
        bootstrap = np.broadcast_to(np.asarray(last_values, dtype=np.float64), values64.shape[1:])

    if variant == "supplement":
        bonus = _supplement_bonus(values64, starts, bootstrap, has_bootstrap)
        return bonus.astype(out_dtype, copy=False)
    log_norm, entropy_before, entropy_after = _running_window_stats(values64, starts)
    if variant == "code":
        bonus = np.where(entropy_before > entropy_after, entropy_before, 0.0)
    else:
        bonus = _paper_bonus(values64, log_norm, starts, bootstrap, has_bootstrap)
    return bonus.astype(out_dtype, copy=False)


def _bootstrap_mask(shape: tuple[int, ...], last_values: np.ndarray | None, last_dones: np.ndarray | None) -> np.ndarray:
    """
    Where the bootstrap value continues the episode of the last step.

    :param shape: Shape of the values, ``(T, ...)``.
    :param last_values: Bootstrap values or None.
    :param last_dones: Whether the last step ended its episode, ``shape[1:]`` aligned from the left, or None.
    :return: Boolean array of shape ``shape[1:]``.
    """
    trailing = shape[1:]
    if last_values is None:
        return np.zeros(trailing, dtype=bool)
    if last_dones is None:
        return np.ones(trailing, dtype=bool)
    dones = np.asarray(last_dones).astype(bool)
    if dones.ndim > len(trailing) or dones.shape != trailing[: dones.ndim]:
        raise ValueError(f"`last_dones` of shape {dones.shape} does not match values of shape {shape}")
    # (a,) -> (a, 1, ..., 1) so that broadcasting aligns the leading axes
    dones = dones.reshape(dones.shape + (1,) * (len(trailing) - dones.ndim))
    return np.broadcast_to(~dones, trailing)


def _broadcast_starts(episode_starts: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """
    Broadcast episode starts to ``shape``, aligning axes from the left (time first).

    :param episode_starts: Array of shape ``(T, ...)``.
    :param shape: Shape of the values, ``(T, ...)``.
    :return: Boolean array of shape ``shape``.
    """
    starts = np.asarray(episode_starts).astype(bool)
    if starts.ndim == 0 or starts.ndim > len(shape) or starts.shape[0] != shape[0]:
        raise ValueError(f"`episode_starts` of shape {starts.shape} does not match values of shape {shape}")
    # (T, a, b) -> (T, a, b, 1, ..., 1) so that NumPy broadcasting aligns the leading axes
    starts = starts.reshape(starts.shape + (1,) * (len(shape) - starts.ndim))
    return np.broadcast_to(starts, shape)


def _running_window_stats(values: np.ndarray, starts: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    One O(T) pass over time, vectorised over the trailing axes.

    :param values: Float64 array ``(T, ...)``.
    :param starts: Boolean array ``(T, ...)`` or None (one window for the whole rollout).
    :return: ``log_norm[t]`` = log-sum-exp of the window values up to and including ``t``;
        ``entropy_before[t]`` = :math:`H_t` (window up to ``t - 1``); ``entropy_after[t]`` = :math:`H_{t+1}`
        (window up to ``t``). All of shape ``(T, ...)``.
    """
    log_norm = np.empty_like(values)
    entropy_before = np.empty_like(values)
    entropy_after = np.empty_like(values)
    prev_log_norm = np.full(values.shape[1:], -np.inf)  # L_0 = log(0): empty window
    entropy = np.zeros(values.shape[1:])  # H_0 = 0
    for t in range(values.shape[0]):
        if starts is not None:
            prev_log_norm = np.where(starts[t], -np.inf, prev_log_norm)
            entropy = np.where(starts[t], 0.0, entropy)
        entropy_before[t] = entropy
        new_log_norm = np.logaddexp(prev_log_norm, values[t])
        log_share = values[t] - new_log_norm  # log q_t, q_t = share of the new step
        empty = np.isneginf(prev_log_norm)
        log_keep = np.where(empty, 0.0, prev_log_norm - new_log_norm)  # log(1 - q_t), finite placeholder if empty
        keep = np.where(empty, 0.0, np.exp(log_keep))  # 1 - q_t
        entropy = -np.exp(log_share) * log_share - keep * log_keep + keep * entropy
        entropy_after[t] = entropy
        log_norm[t] = new_log_norm
        prev_log_norm = new_log_norm
    return log_norm, entropy_before, entropy_after


def _has_next(values: np.ndarray, starts: np.ndarray | None, has_bootstrap: np.ndarray) -> np.ndarray:
    """
    Where step ``t`` has a successor in its own episode (the next stored step, or the bootstrap for the last one).

    :param values: Float64 array ``(T, ...)``.
    :param starts: Boolean episode starts ``(T, ...)`` or None.
    :param has_bootstrap: ``(...)`` where the bootstrap continues the last step's episode.
    :return: Boolean array ``(T, ...)``.
    """
    has_next = np.ones(values.shape, dtype=bool)
    has_next[-1] = has_bootstrap
    if starts is not None:
        has_next[:-1] &= ~starts[1:]  # no look-ahead across an episode boundary
    return has_next


def _paper_bonus(
    values: np.ndarray,
    log_norm: np.ndarray,
    starts: np.ndarray | None,
    bootstrap: np.ndarray | None,
    has_bootstrap: np.ndarray,
) -> np.ndarray:
    """
    Literal Eqs. 12-14: per-state entropy term with the window ending at t vs. at t + 1.

    :param values: Float64 array ``(T, ...)``.
    :param log_norm: Log-sum-exp of the window up to and including ``t``, ``(T, ...)``.
    :param starts: Boolean episode starts ``(T, ...)`` or None.
    :param bootstrap: Look-ahead values for the last step, ``values.shape[1:]``, or None.
    :param has_bootstrap: ``(...)`` where the bootstrap continues the last step's episode.
    :return: The bonus, ``(T, ...)``.
    """
    next_values = np.empty_like(values)
    next_values[:-1] = values[1:]
    next_values[-1] = 0.0 if bootstrap is None else np.where(has_bootstrap, bootstrap, 0.0)
    has_next = _has_next(values, starts, has_bootstrap)

    log_p_now = values - log_norm  # log p_t(t+1), (T, ...)
    log_p_next = values - np.logaddexp(log_norm, next_values)  # log p_t(t+2), (T, ...)
    term_now = -np.exp(log_p_now) * log_p_now
    term_next = -np.exp(log_p_next) * log_p_next
    return np.where(has_next & (term_now > term_next), term_now, 0.0)


def _supplement_bonus(
    values: np.ndarray, starts: np.ndarray | None, bootstrap: np.ndarray | None, has_bootstrap: np.ndarray
) -> np.ndarray:
    """
    The supplement reading: per-state term of a softmax over the whole window, fired when the next term is lower.

    A forward pass gives the running log-sum-exp of each window, a backward pass spreads the window's total to
    all of its steps (the last window's total includes the bootstrap where it continues the episode).

    :param values: Float64 array ``(T, ...)``.
    :param starts: Boolean episode starts ``(T, ...)`` or None.
    :param bootstrap: Bootstrap values ``values.shape[1:]`` or None.
    :param has_bootstrap: ``(...)`` where the bootstrap continues the last step's episode.
    :return: The bonus, ``(T, ...)``.
    """
    n_steps = values.shape[0]
    running = np.empty_like(values)  # log-sum-exp of the window up to and including t
    previous = np.full(values.shape[1:], -np.inf)
    for t in range(n_steps):
        if starts is not None:
            previous = np.where(starts[t], -np.inf, previous)
        previous = np.logaddexp(previous, values[t])
        running[t] = previous
    window_total = np.empty_like(values)  # log-sum-exp of the whole window of step t
    total = running[-1]
    if bootstrap is not None:
        total = np.where(has_bootstrap, np.logaddexp(total, np.where(has_bootstrap, bootstrap, 0.0)), total)
    window_total[-1] = total
    for t in range(n_steps - 2, -1, -1):
        window_total[t] = running[t] if starts is None else np.where(starts[t + 1], running[t], window_total[t + 1])
    if starts is None:
        window_total[:] = window_total[-1]  # one window: every step shares the last total (with the bootstrap)

    log_p = values - window_total  # (T, ...)
    term = -np.exp(log_p) * log_p
    next_term = np.zeros_like(values)
    next_term[:-1] = term[1:]
    if bootstrap is not None:
        log_p_bootstrap = np.where(has_bootstrap, bootstrap, 0.0) - window_total[-1]
        next_term[-1] = -np.exp(log_p_bootstrap) * log_p_bootstrap
    has_next = _has_next(values, starts, has_bootstrap)
    return np.where(has_next & (term > next_term), term, 0.0)


def value_softmax_entropy(values: np.ndarray) -> np.ndarray:
    """Entropy of the softmax over time of each series of stored values: the "system entropy" of the whole window
    (the paper's Fig. 1 idea), ``H = log sum_t exp(v_t) - sum_t p_t v_t``.

    :param values: ``(T, ...)`` time-first
    :return: ``(...)``
    """
    values = np.asarray(values, dtype=np.float64)
    log_sum = np.logaddexp.reduce(values, axis=0)
    probs = np.exp(values - log_sum)
    return log_sum - (probs * values).sum(axis=0)


@register_intrinsic_reward("saeir")
class SAEIRCallback(IntrinsicRewardCallback):
    """SAEIR as a callback: the bonus of every critic scale from that scale's stored values (``docs/method.md``,
    "The intrinsic reward").

    For each scale K, game and agent, ``saeir_bonus`` runs over the rollout window of the stored (normalised,
    detached) critic outputs; ``coef * bonus`` enters only that scale's TD errors (``docs/method.md``, "GAE per
    scale"). Added automatically by ``SAEIR_PPO(intrinsic_reward="saeir")``; with ``intrinsic_reward=None`` it can be
    passed to ``learn`` explicitly (the SAE-only ablation uses it on a single MAPPO critic).

    Logs ``rollout/intrinsic_reward_mean`` (unscaled, all scales), and per scale
    ``rollout/intrinsic_reward_mean_<scale>``, ``rollout/intrinsic_fire_rate_<scale>`` (fraction of steps where
    the bonus fired) and ``rollout/value_entropy_<scale>`` (entropy of the value softmax over the whole window).

    :param coef: beta (0.1 in the released code)
    :param variant: ``"code"`` (released code, default), ``"paper"`` (Eqs. 12-14 literally) or ``"supplement"``
        (whole-window softmax, the reading that reproduces the supplement's Fig. 3)
    :param reset_at_episode_start: restart the entropy window at episode starts instead of using the whole rollout
        window (the authors' behaviour); identical for Cooperative Navigation with ``n_steps`` = episode length
    :param verbose: verbosity
    """

    def __init__(
        self, coef: float = 0.1, variant: str = "code", reset_at_episode_start: bool = False, verbose: int = 0
    ) -> None:
        check_saeir_variant(variant)
        check_bool("SAEIRCallback", reset_at_episode_start=reset_at_episode_start)
        super().__init__(coef=coef, name="intrinsic", verbose=verbose)
        self.variant = variant
        self.reset_at_episode_start = reset_at_episode_start

    def compute_bonus(self, buffer: GroupedRecurrentRolloutBuffer) -> np.ndarray:
        episode_starts = buffer.episode_starts if self.reset_at_episode_start else None
        # the look-ahead of the last step: the bootstrap value, unless that step ended the episode
        return saeir_bonus(  # (T, E, K)
            buffer.values,
            variant=self.variant,
            episode_starts=episode_starts,
            last_values=buffer.last_values,
            last_dones=buffer.last_dones,
        )

    def _log_bonus(self, bonus: np.ndarray, buffer: GroupedRecurrentRolloutBuffer) -> None:
        self.logger.record("rollout/intrinsic_reward_mean", float(bonus.mean()))
        window_entropy = value_softmax_entropy(buffer.values)  # (E, K)
        scales = getattr(self.model.policy, "scales", tuple(f"scale{k}" for k in range(bonus.shape[-1])))
        for k, scale in enumerate(scales):
            self.logger.record(f"rollout/intrinsic_reward_mean_{scale}", float(bonus[..., k].mean()))
            self.logger.record(f"rollout/intrinsic_fire_rate_{scale}", float((bonus[..., k] > 0).mean()))
            self.logger.record(f"rollout/value_entropy_{scale}", float(window_entropy[..., k].mean()))
