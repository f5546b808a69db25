import itertools
import math

import numpy as np
import pytest

from sb3_saeir.intrinsic import saeir_bonus


def _code_reference_1d(series: np.ndarray) -> np.ndarray:
    """Slow O(T^2) double loop of the released code (docs/method.md, "The intrinsic reward"), with the code's 1e-8
    clamps and plain exp."""
    n_steps = len(series)

    def prefix_entropy(n: int) -> float:
        if n == 0:
            return 0.0
        total = max(sum(math.exp(series[j]) for j in range(n)), 1e-8)
        entropy = 0.0
        for j in range(n):
            p = math.exp(series[j]) / total
            entropy -= p * math.log(max(p, 1e-8))
        return entropy

    entropies = [prefix_entropy(n) for n in range(n_steps + 1)]
    return np.array([entropies[t] if entropies[t] > entropies[t + 1] else 0.0 for t in range(n_steps)])


def _shifted_code_reference_1d(series: np.ndarray) -> np.ndarray:
    """
    O(T^2) reference of the released code with a max-shift in every prefix (safe for |v| ~ 1e3).

    Returns the bonus and the margin H_t - H_{t+1}; near-ties (|margin| < 1e-9) are returned as NaN bonus,
    because there the rounding of this reference, not the maths, decides the comparison.
    """
    n_steps = len(series)
    entropies = [0.0]
    for n in range(1, n_steps + 1):
        prefix = series[:n] - series[:n].max()
        p = np.exp(prefix) / np.exp(prefix).sum()
        p = p[p > 0]
        entropies.append(float(-(p * np.log(p)).sum()))
    bonus = []
    for t in range(n_steps):
        margin = entropies[t] - entropies[t + 1]
        bonus.append(math.nan if abs(margin) < 1e-9 else (entropies[t] if margin > 0 else 0.0))
    return np.array(bonus)


def _paper_reference_1d(series: np.ndarray, last_value: float | None) -> np.ndarray:
    """Slow literal loop of Eqs. 12-14: per-state term with windows [0, t] ("T") and [0, t + 1] ("T+1")."""
    extended = list(series) + ([] if last_value is None else [last_value])
    bonus = np.zeros(len(series))
    for t in range(len(series)):
        if t + 1 >= len(extended):
            continue  # no look-ahead available
        p_now = math.exp(extended[t]) / sum(math.exp(extended[j]) for j in range(t + 1))
        p_next = math.exp(extended[t]) / sum(math.exp(extended[j]) for j in range(t + 2))
        e_now = -p_now * math.log(p_now)
        e_next = -p_next * math.log(p_next)
        bonus[t] = e_now if e_now > e_next else 0.0
    return bonus


def _apply_1d(reference, values: np.ndarray, *args) -> np.ndarray:
    """Apply a 1-d reference to every trailing index of a time-first array."""
    flat = values.reshape(values.shape[0], -1)  # (T, n_series)
    out = np.stack([reference(flat[:, k], *[a[k] for a in args]) for k in range(flat.shape[1])], axis=1)
    return out.reshape(values.shape)


@pytest.fixture
def random_values() -> np.ndarray:
    return np.random.default_rng(0).normal(0.0, 1.5, size=(30, 4, 3, 3))


def test_code_variant_matches_quadratic_reference(random_values):
    bonus = saeir_bonus(random_values)
    expected = _apply_1d(_code_reference_1d, random_values)
    assert bonus.shape == random_values.shape
    assert bonus.dtype == np.float64
    assert np.max(np.abs(bonus - expected)) < 1e-6
    assert 0 < np.count_nonzero(expected) < expected.size  # the test exercises both branches


def test_worked_example():
    bonus = saeir_bonus(np.array([0.0, 0.0, 2.0, 0.5, 3.0]))
    np.testing.assert_allclose(bonus, [0.0, 0.0, math.log(2.0), 0.0, 0.0], atol=1e-12)
    assert bonus[2] == pytest.approx(0.6931, abs=1e-4)


def test_first_two_steps_never_fire(random_values):
    bonus = saeir_bonus(random_values * 3.0)
    assert np.all(bonus[:2] == 0.0)
    assert np.all(bonus >= 0.0)


def test_float32_dtype_is_kept(random_values):
    bonus = saeir_bonus(random_values.astype(np.float32))
    assert bonus.dtype == np.float32
    assert saeir_bonus(np.arange(6)).dtype == np.float64


@pytest.mark.parametrize("with_last_values", [False, True])
def test_paper_variant_matches_literal_loop(random_values, with_last_values):
    last_values = np.random.default_rng(1).normal(0.0, 1.5, size=random_values.shape[1:]) if with_last_values else None
    bonus = saeir_bonus(random_values, variant="paper", last_values=last_values)
    if with_last_values:
        expected = _apply_1d(_paper_reference_1d, random_values, last_values.reshape(-1))
    else:
        expected = _apply_1d(_paper_reference_1d, random_values, [None] * (random_values[0].size))
    assert np.max(np.abs(bonus - expected)) < 1e-9
    assert np.count_nonzero(expected) > 0
    if not with_last_values:
        assert np.all(bonus[-1] == 0.0)
    else:
        assert np.count_nonzero(bonus[-1]) > 0


def test_code_variant_ignores_last_values(random_values):
    last_values = np.full(random_values.shape[1:], 50.0)
    np.testing.assert_array_equal(saeir_bonus(random_values), saeir_bonus(random_values, last_values=last_values))


def _random_starts(rng: np.random.Generator, n_steps: int, n_envs: int) -> np.ndarray:
    starts = rng.random((n_steps, n_envs)) < 0.15
    starts[0, 0] = True
    return starts


@pytest.mark.parametrize("variant", ["code", "paper", "supplement"])
@pytest.mark.parametrize("with_last_values", [False, True])
def test_episode_starts_equal_separate_segments(random_values, variant, with_last_values):
    rng = np.random.default_rng(2)
    starts = _random_starts(rng, random_values.shape[0], random_values.shape[1])  # (T, n_envs), left-aligned
    last_values = rng.normal(0.0, 1.5, size=random_values.shape[1:]) if with_last_values else None
    bonus = saeir_bonus(random_values, variant=variant, episode_starts=starts, last_values=last_values)

    expected = np.zeros_like(random_values)
    for env in range(random_values.shape[1]):
        boundaries = [0, *[t for t in range(1, random_values.shape[0]) if starts[t, env]], random_values.shape[0]]
        for begin, end in itertools.pairwise(boundaries):
            is_last_segment = end == random_values.shape[0]
            segment_last = last_values[env] if (is_last_segment and last_values is not None) else None
            expected[begin:end, env] = saeir_bonus(random_values[begin:end, env], variant=variant, last_values=segment_last)
    np.testing.assert_allclose(bonus, expected, atol=1e-12)
    # same result with episode_starts given at the full shape
    full_starts = np.broadcast_to(starts[:, :, None, None], random_values.shape)
    full = saeir_bonus(random_values, variant=variant, episode_starts=full_starts, last_values=last_values)
    np.testing.assert_array_equal(bonus, full)
    # and the resets actually change something
    assert not np.allclose(bonus, saeir_bonus(random_values, variant=variant, last_values=last_values))


def test_episode_starts_reset_code_reference():
    values = np.random.default_rng(3).normal(0.0, 1.5, size=(20,))
    starts = np.zeros(20, dtype=bool)
    starts[[0, 7, 8, 15]] = True
    bonus = saeir_bonus(values, episode_starts=starts)
    expected = np.concatenate(
        [
            _code_reference_1d(values[0:7]),
            _code_reference_1d(values[7:8]),
            _code_reference_1d(values[8:15]),
            _code_reference_1d(values[15:]),
        ]
    )
    np.testing.assert_allclose(bonus, expected, atol=1e-6)
    assert np.all(bonus[[0, 1, 7, 8, 9, 15, 16]] == 0.0)  # first two steps of every episode never fire


@pytest.mark.parametrize("scale", [500.0, 1000.0])
def test_numerical_stability_large_values(scale):
    rng = np.random.default_rng(4)
    values = rng.choice([-scale, scale], size=(40, 3, 2)) + rng.normal(0.0, 1.5, size=(40, 3, 2))
    with np.errstate(over="raise", invalid="raise", divide="raise"):  # underflow to 0 is benign
        bonus = saeir_bonus(values)
        paper = saeir_bonus(values, variant="paper", last_values=values[-1])
        supplement = saeir_bonus(values, variant="supplement", last_values=values[-1])
    assert np.all(np.isfinite(bonus)) and np.all(np.isfinite(paper)) and np.all(np.isfinite(supplement))
    expected = _apply_1d(_shifted_code_reference_1d, values)
    clear = ~np.isnan(expected)
    assert clear.mean() > 0.3 and np.count_nonzero(expected[clear]) > 0
    np.testing.assert_allclose(bonus[clear], expected[clear], atol=1e-6)
    # near-ties happen when a value far below the window is appended: its share q underflows, so H_{t+1} = H_t
    # up to rounding, while in exact arithmetic the bonus fires only if H_t > h(q)/q ~ 1 - log q (huge): no bonus
    assert np.all(bonus[~clear] == 0.0)


@pytest.mark.parametrize("variant", ["code", "paper", "supplement"])
def test_shift_invariance(random_values, variant):
    base = saeir_bonus(random_values, variant=variant, last_values=random_values[0])
    shifted = saeir_bonus(random_values + 900.0, variant=variant, last_values=random_values[0] + 900.0)
    np.testing.assert_allclose(shifted, base, atol=1e-9)


def test_empty_rollout():
    assert saeir_bonus(np.zeros((0, 3)), variant="paper").shape == (0, 3)


def test_errors():
    with pytest.raises(ValueError, match="Unknown SAEIR variant"):
        saeir_bonus(np.zeros(5), variant="codes")
    with pytest.raises(ValueError, match="time axis"):
        saeir_bonus(np.array(1.0))
    with pytest.raises(ValueError, match="episode_starts"):
        saeir_bonus(np.zeros((5, 2)), episode_starts=np.zeros((4, 2)))


def test_value_softmax_entropy_closed_form():
    from sb3_saeir.intrinsic.saeir import value_softmax_entropy

    values = np.array([[0.0, 1.0], [0.0, 1.0], [np.log(2.0), 1.0]])  # (T=3, 2 series)
    p = np.array([1.0, 1.0, 2.0]) / 4.0
    np.testing.assert_allclose(value_softmax_entropy(values), [-(p * np.log(p)).sum(), np.log(3.0)], atol=1e-12)


def _supplement_reference_1d(series, starts=None, last_value=None, last_done=False):
    """Slow loop of the supplement reading (docs/method.md, "Supplement variant"), one series: split the rollout
    into windows at the episode starts, append the bootstrap to the last window when it continues the episode, one
    softmax per window, and reward step t with -p_t log p_t when the next entry's term is lower."""
    n_steps = len(series)
    begins = [0] + [t for t in range(1, n_steps) if starts is not None and starts[t]]
    ends = [*begins[1:], n_steps]
    bonus = [0.0] * n_steps
    for begin, end in zip(begins, ends, strict=True):
        window = [float(series[t]) for t in range(begin, end)]
        if end == n_steps and last_value is not None and not last_done:
            window.append(float(last_value))
        total = sum(math.exp(v) for v in window)
        terms = [-(math.exp(v) / total) * math.log(math.exp(v) / total) for v in window]
        for i in range(end - begin):
            if i + 1 < len(window) and terms[i] > terms[i + 1]:
                bonus[begin + i] = terms[i]
    return np.array(bonus)


@pytest.mark.parametrize("with_last_values", [False, True])
def test_supplement_variant_matches_slow_loop(random_values, with_last_values):
    rng = np.random.default_rng(5)
    last_values = rng.normal(0.0, 1.5, size=random_values.shape[1:]) if with_last_values else None
    bonus = saeir_bonus(random_values, variant="supplement", last_values=last_values)
    flat = random_values.reshape(random_values.shape[0], -1)  # (T, n_series)
    flat_last = [None] * flat.shape[1] if last_values is None else last_values.reshape(-1)
    expected = np.stack(
        [_supplement_reference_1d(flat[:, k], last_value=flat_last[k]) for k in range(flat.shape[1])], axis=1
    ).reshape(random_values.shape)
    assert np.max(np.abs(bonus - expected)) < 1e-12
    assert 0 < np.count_nonzero(expected) < expected.size
    assert np.count_nonzero(bonus[0]) > 0  # unlike the other readings, step 0 can fire
    if with_last_values:
        assert np.count_nonzero(bonus[-1]) > 0
    else:
        assert np.all(bonus[-1] == 0.0)


def test_supplement_variant_with_episode_starts_and_last_dones(random_values):
    rng = np.random.default_rng(6)
    n_steps, n_envs = random_values.shape[:2]
    starts = _random_starts(rng, n_steps, n_envs)  # (T, n_envs), left-aligned
    last_values = rng.normal(0.0, 1.5, size=random_values.shape[1:])
    last_dones = rng.random(n_envs) < 0.5  # (n_envs,), left-aligned
    last_dones[:2] = [True, False]
    bonus = saeir_bonus(
        random_values, variant="supplement", episode_starts=starts, last_values=last_values, last_dones=last_dones
    )
    expected = np.zeros_like(random_values)
    for env in range(n_envs):
        for index in np.ndindex(random_values.shape[2:]):
            expected[(slice(None), env, *index)] = _supplement_reference_1d(
                random_values[(slice(None), env, *index)], starts[:, env], last_values[(env, *index)], last_dones[env]
            )
    assert np.max(np.abs(bonus - expected)) < 1e-12
    assert np.all(bonus[-1, last_dones] == 0.0)
    assert np.count_nonzero(bonus[-1, ~last_dones]) > 0
    # the last step of every episode that ends inside the rollout never fires
    ends_inside = np.zeros(random_values.shape, dtype=bool)
    ends_inside[:-1] = np.broadcast_to(starts[1:, :, None, None], ends_inside[:-1].shape)
    assert np.all(bonus[ends_inside] == 0.0)


def test_supplement_variant_worked_example():
    # window [0, 0, log 2] + bootstrap 0: p = [1, 1, 2, 1] / 5
    bonus = saeir_bonus(np.array([0.0, 0.0, math.log(2.0)]), variant="supplement", last_values=np.array(0.0))
    small, large = -0.2 * math.log(0.2), -0.4 * math.log(0.4)
    np.testing.assert_allclose(bonus, [0.0, 0.0, large], atol=1e-12)  # 0: equal next term; 1: next is larger
    assert large > small


def test_supplement_variant_on_near_flat_values():
    """Fig. 3's arithmetic: with near-flat values p ~ 1/26 over 25 steps + bootstrap, the term is log(26)/26 and fires
    when the next state's value is lower, about half of the steps."""
    rng = np.random.default_rng(7)
    values = rng.normal(0.0, 0.02, size=(25, 2000))
    bonus = saeir_bonus(values, variant="supplement", last_values=rng.normal(0.0, 0.02, size=2000))
    fired = bonus > 0
    assert abs(fired.mean() - 0.5) < 0.02
    assert 0.1 * bonus[fired].mean() == pytest.approx(0.1 * math.log(26.0) / 26.0, rel=0.01)  # 0.0125
    assert abs(fired[0].mean() - 0.5) < 0.05


@pytest.mark.parametrize("variant", ["paper", "supplement"])
def test_last_dones_mean_no_look_ahead(random_values, variant):
    last_values = np.random.default_rng(8).normal(0.0, 1.5, size=random_values.shape[1:])
    all_done = saeir_bonus(random_values, variant=variant, last_values=last_values, last_dones=np.ones(4))
    np.testing.assert_array_equal(all_done, saeir_bonus(random_values, variant=variant))
    none_done = saeir_bonus(random_values, variant=variant, last_values=last_values, last_dones=np.zeros(4))
    np.testing.assert_array_equal(none_done, saeir_bonus(random_values, variant=variant, last_values=last_values))
    with pytest.raises(ValueError, match="last_dones"):
        saeir_bonus(random_values, variant=variant, last_values=last_values, last_dones=np.zeros(5))
