"""Tests for the quantum-like Bayesian (QLB) library; its figure script: tests/studies/test_qlb_figures.py."""

from __future__ import annotations

import itertools
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crossing_env.pedestrians.force_update import (
    PED_PED_INTENSITY,
    VEHICLE_PED_INTENSITY,
    ForceUpdateConfig,
    classical_updated_force_intensity,
    updated_force_intensity,
)
from crossing_env.pedestrians.quantum import (
    disjunction_probabilities,
    disjunction_probability,
    heuristic_rule,
    interference_probability,
    pairwise_interference_probability,
    similarity_geometry,
    similarity_phase,
    triangle_angles,
)
from predictors import qlb
from predictors.qlb import (
    CASES,
    Node,
    QuantumLikeBayesNet,
    cbm_cross_probability,
    crossing_network,
    crossing_neutral_phases,
    crossing_pair_cosines,
    qlb_cross_probability,
)

REPO = Path(__file__).resolve().parents[2]
unit = st.floats(min_value=0.0, max_value=1.0, allow_nan=False)
angle = st.floats(min_value=-2 * math.pi, max_value=2 * math.pi, allow_nan=False)


# --------------------------------------------------------------------------------------------------------
# Worked examples (M&W 2016, Section 7). The conditional probabilities are the experiments' published
# two-stage data as quoted in M&W 2016 and our notes; the search tool only returned the paper's abstract,
# so the QLB values below are derived by hand here (not copied from the paper's tables).
# --------------------------------------------------------------------------------------------------------
def test_prisoners_dilemma_shafir_tversky_1992() -> None:
    # P(D | opponent D) = 0.97, P(D | opponent C) = 0.84, prior 0.5; observed P(D | unknown) = 0.63.
    # a = [0.485, 0.42], b = [0.015, 0.08], c = a - b = [0.47, 0.34]
    # |a| = 0.641580, |b| = 0.081394, |c| = 0.580086
    # theta_C = acos(a.b / |a||b|) = acos(0.040875 / 0.052221) = acos(0.782729) = 0.671750
    # theta_A = acos((|b|^2 + |c|^2 - |a|^2) / (2|b||c|)) = acos(-0.0685 / 0.094431) = 2.382406
    # theta_B = pi - theta_A - theta_C = 0.087437
    # phi = (0.671750 - 0.087437) / 2.382406 = 0.245262 > 0.2  ->  theta = pi - theta_C / 2 = 2.805718
    # cos(theta) = -0.944122: T = 0.905 - 2 sqrt(0.2037) 0.9443 = 0.052776, F = 0.095 - 2 sqrt(0.0012) 0.9443
    # = 0.029589  ->  P = 0.052776 / 0.082365 = 0.640756 (classical 0.905, observed 0.63)
    ta, tb, tc, phi = similarity_geometry([0.485, 0.42], [0.015, 0.08])
    assert float(tc) == pytest.approx(0.671750, abs=1e-6)
    assert float(ta) == pytest.approx(2.382406, abs=1e-6)
    assert float(tb) == pytest.approx(0.087437, abs=1e-6)
    assert float(phi) == pytest.approx(0.245262, abs=1e-6)
    assert float(similarity_phase([0.485, 0.42], [0.015, 0.08])) == pytest.approx(2.805718, abs=1e-6)
    p_qlb = disjunction_probability(0.97, 0.84)
    assert p_qlb == pytest.approx(0.640756, abs=1e-6)
    assert disjunction_probability(0.97, 0.84, theta=math.pi / 2) == pytest.approx(0.905, abs=1e-12)
    # The QLB prediction is much closer to the observed 0.63 than the classical 0.905.
    assert abs(p_qlb - 0.63) < 0.02 < abs(0.905 - 0.63)


def test_two_stage_gamble_tversky_shafir_1992_hits_the_pi_branch() -> None:
    # P(play | won) = 0.69, P(play | lost) = 0.59, prior 0.5; observed P(play | unknown) = 0.36.
    # a = [0.345, 0.295], b = [0.155, 0.205]; phi = -0.018449 < 0  ->  theta = pi, cos = -1:
    # T = (sqrt(0.345) - sqrt(0.295))^2 = (0.587367 - 0.543139)^2 = 0.0019561
    # F = (sqrt(0.155) - sqrt(0.205))^2 = (0.393700 - 0.452769)^2 = 0.0034891
    # P = 0.0019561 / 0.0054452 = 0.359233 (classical 0.64)
    phi = similarity_geometry([0.345, 0.295], [0.155, 0.205])[3]
    assert float(phi) == pytest.approx(-0.018449, abs=1e-6)
    assert float(similarity_phase([0.345, 0.295], [0.155, 0.205])) == math.pi
    assert disjunction_probability(0.69, 0.59) == pytest.approx(0.359233, abs=1e-6)


def test_middle_branch_example() -> None:
    # P = 0.9 / 0.8, prior 0.5: a = [0.45, 0.4], b = [0.05, 0.1]; phi = 0.1110 in [0, 0.2]
    # theta_C = acos(0.0625 / (0.602080 * 0.111803)) = acos(0.928477) = 0.380506  ->  theta = pi - theta_C
    # T = 0.85 - 2 sqrt(0.18) 0.928477 = 0.062161, F = 0.15 - 2 sqrt(0.005) 0.928477 = 0.018694
    # P = 0.062161 / 0.080855 = 0.768801
    phi = float(similarity_geometry([0.45, 0.4], [0.05, 0.1])[3])
    assert 0.0 <= phi <= 0.2
    assert float(similarity_phase([0.45, 0.4], [0.05, 0.1])) == pytest.approx(math.pi - 0.380506, abs=1e-6)
    assert disjunction_probability(0.9, 0.8) == pytest.approx(0.768801, abs=1e-6)


# --------------------------------------------------------------------------------------------------------
# The heuristic rule and its geometry
# --------------------------------------------------------------------------------------------------------
def test_heuristic_rule_branches_and_boundaries() -> None:
    ta = np.array([1.0, 1.0, 1.0, 2.5, 1.0])
    tb = np.array([0.5, 0.3, 0.1, 0.25, 0.4])
    tc = np.array([0.4, 0.4, 0.5, 0.75, 0.4])
    # phi = -0.1 (pi), 0.1 (pi - tc), 0.4 (pi - tc / 2), exactly 0.2 (pi - tc), exactly 0 (pi - tc)
    expected = [math.pi, math.pi - 0.4, math.pi - 0.25, math.pi - 0.75, math.pi - 0.4]
    np.testing.assert_allclose(heuristic_rule(ta, tb, tc), expected, rtol=0, atol=1e-15)


def test_all_three_branches_reached_from_probabilities() -> None:
    a = np.array([[0.345, 0.295], [0.45, 0.4], [0.485, 0.42]])
    b = np.array([[0.155, 0.205], [0.05, 0.1], [0.015, 0.08]])
    _, _, tc, phi = similarity_geometry(a, b)
    assert phi[0] < 0.0 <= phi[1] <= 0.2 < phi[2]
    np.testing.assert_allclose(similarity_phase(a, b), [math.pi, math.pi - tc[1], math.pi - tc[2] / 2])


def test_fast_path_matches_law_of_cosines() -> None:
    rng = np.random.default_rng(7)
    a = rng.random((2000, 2))
    b = rng.random((2000, 2))
    na, nb, nc = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1), np.linalg.norm(a - b, axis=1)
    ta, tb, tc = triangle_angles(na, nb, nc)
    np.testing.assert_allclose(ta + tb + tc, math.pi, atol=1e-9)
    np.testing.assert_allclose(similarity_phase(a, b), heuristic_rule(ta, tb, tc), atol=1e-9)


def test_misprinted_norm_c_gives_constant_pi_but_correct_one_does_not() -> None:
    rng = np.random.default_rng(3)
    a = rng.random((500, 2))
    b = rng.random((500, 2))
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    # Song et al. (2022): ||c|| = ||a|| - ||b||  ->  flat triangle, theta = pi for every input.
    misprint = heuristic_rule(*triangle_angles(na, nb, na - nb))
    np.testing.assert_allclose(misprint, math.pi, atol=1e-7)
    # M&W 2016: ||c|| = ||a - b||  ->  theta < pi wherever phi >= 0 and a, b are not parallel.
    _, _, tc, phi = similarity_geometry(a, b)
    correct = similarity_phase(a, b)
    nonneg = (phi >= 0.0) & (tc > 1e-6)
    assert nonneg.sum() > 50
    assert np.all(correct[nonneg] < math.pi)
    assert np.all(correct[phi < 0.0] == math.pi)


def test_degenerate_geometry_falls_back_to_classical() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = np.array([[0.0, 0.0], [0.3, 0.2], [0.25, 0.25], [0.4, 0.1]])
        b = np.array([[0.5, 0.5], [0.0, 0.0], [0.25, 0.25], [0.4, 0.1]])
        np.testing.assert_array_equal(similarity_phase(a, b), np.full(4, math.pi / 2))
        assert np.all(np.isnan(similarity_geometry(a, b)[3]))
        # a = b: P(query | cause) = 0.5 for both causes.
        assert disjunction_probability(0.5, 0.5) == pytest.approx(0.5, abs=1e-15)
        # a parallel to b but not equal: theta = pi cancels both scores; the classical value comes back.
        assert disjunction_probability(0.6, 0.6) == pytest.approx(0.6, abs=1e-12)
        # zero vectors and certain priors: no interference possible.
        assert disjunction_probability(1.0, 1.0) == pytest.approx(1.0)
        assert disjunction_probability(0.0, 0.0) == pytest.approx(0.0)
        assert disjunction_probability(0.3, 0.9, prior_a=1.0) == pytest.approx(0.3)
        assert disjunction_probability(0.3, 0.9, prior_a=0.0) == pytest.approx(0.9)


def test_bad_inputs_raise_clear_errors() -> None:
    with pytest.raises(ValueError, match="p_true_given_a"):
        disjunction_probability(1.2, 0.5)
    with pytest.raises(ValueError, match="prior_a"):
        disjunction_probability(0.5, 0.5, prior_a=float("nan"))
    with pytest.raises(ValueError, match="theta"):
        disjunction_probability(0.5, 0.4, theta=float("inf"))
    with pytest.raises(ValueError, match="cos_theta"):
        interference_probability(0.1, 0.2, 0.3, 0.4, 1.5)
    with pytest.raises(ValueError, match="q1"):
        interference_probability(0.1, 0.2, -0.3, 0.4, 0.0)
    with pytest.raises(ValueError, match="zero probability"):
        interference_probability(0.0, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="shape"):
        similarity_phase([0.1, 0.2, 0.3], [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="same shape"):
        pairwise_interference_probability(np.ones(3), np.ones(4))


# --------------------------------------------------------------------------------------------------------
# Quantum marginal: classical collapse, normalisation, range
# --------------------------------------------------------------------------------------------------------
@settings(max_examples=200, deadline=None)
@given(unit, unit, unit, unit, st.floats(min_value=-1.0, max_value=1.0))
def test_interference_probability_properties(p1: float, p2: float, q1: float, q2: float, c: float) -> None:
    if p1 + p2 + q1 + q2 == 0.0:
        return
    p = float(interference_probability(p1, p2, q1, q2, c))
    assert 0.0 <= p <= 1.0
    # The same theta for both outcomes, normalised over the pair: the two outcomes sum to 1.
    assert p + float(interference_probability(q1, q2, p1, p2, c)) == pytest.approx(1.0, abs=1e-9)
    # cos = 0: exactly the classical posterior.
    assert float(interference_probability(p1, p2, q1, q2, 0.0)) == pytest.approx(
        (p1 + p2) / (p1 + p2 + q1 + q2), rel=1e-12, abs=1e-15
    )


@settings(max_examples=200, deadline=None)
@given(unit, unit, unit, st.one_of(st.none(), angle))
def test_disjunction_probability_in_unit_interval(
    pa: float, pb: float, prior: float, theta: float | None
) -> None:
    p = disjunction_probability(pa, pb, prior, theta)
    assert 0.0 <= p <= 1.0
    classical = disjunction_probability(pa, pb, prior, math.pi / 2)
    assert classical == pytest.approx(prior * pa + (1 - prior) * pb, abs=1e-12)


def test_vectorised_matches_scalar_and_broadcasts() -> None:
    rng = np.random.default_rng(11)
    pa, pb, prior = rng.random((3, 200))
    batch = disjunction_probabilities(pa, pb, prior)
    assert batch.shape == (200,)
    scalar = [disjunction_probability(x, y, z) for x, y, z in zip(pa, pb, prior, strict=True)]
    np.testing.assert_allclose(batch, scalar, rtol=0, atol=1e-15)
    assert disjunction_probabilities(pa, 0.5).shape == (200,)
    # m = 2 pairwise form is the two-configuration form.
    p = np.stack([prior * pa, (1 - prior) * pb], axis=-1)
    q = np.stack([prior * (1 - pa), (1 - prior) * (1 - pb)], axis=-1)
    np.testing.assert_allclose(pairwise_interference_probability(p, q), batch, atol=1e-15)


# --------------------------------------------------------------------------------------------------------
# The network: classical = plain Bayes; quantum marginal
# --------------------------------------------------------------------------------------------------------
CLOUDY = {0: 0.5, 1: 0.5}
SPRINKLER = {0: [0.5, 0.5], 1: [0.9, 0.1]}  # P(S | C), states (off, on)
RAIN = {0: [0.8, 0.2, 0.0], 1: [0.1, 0.6, 0.3]}  # P(R | C), states (none, light, heavy)
WET = {  # P(W = wet | S, R)
    (0, 0): 0.0,
    (0, 1): 0.8,
    (0, 2): 0.95,
    (1, 0): 0.9,
    (1, 1): 0.97,
    (1, 2): 0.99,
}


def sprinkler_net(order: tuple[int, ...] = (0, 1, 2, 3)) -> QuantumLikeBayesNet:
    wet = np.array([[[1 - WET[s, r], WET[s, r]] for r in range(3)] for s in range(2)])
    nodes = [
        Node("cloudy", ("no", "yes"), np.array([CLOUDY[0], CLOUDY[1]])),
        Node("sprinkler", ("off", "on"), np.array([SPRINKLER[0], SPRINKLER[1]]), parents=("cloudy",)),
        Node("rain", ("none", "light", "heavy"), np.array([RAIN[0], RAIN[1]]), parents=("cloudy",)),
        Node("wet", ("dry", "wet"), wet, parents=("sprinkler", "rain")),
    ]
    return QuantumLikeBayesNet([nodes[k] for k in order])


def brute_force(query: str, evidence: dict[str, int]) -> np.ndarray:
    """Plain Bayes by nested enumeration, written independently of the library."""
    names = ("cloudy", "sprinkler", "rain", "wet")
    cards = (2, 2, 3, 2)
    scores = np.zeros(cards[names.index(query)])
    for c, s, r, w in itertools.product(*(range(k) for k in cards)):
        values = dict(zip(names, (c, s, r, w), strict=True))
        if any(values[k] != v for k, v in evidence.items()):
            continue
        pw = WET[s, r] if w == 1 else 1 - WET[s, r]
        scores[values[query]] += CLOUDY[c] * SPRINKLER[c][s] * RAIN[c][r] * pw
    return scores / scores.sum()


@pytest.mark.parametrize(
    ("query", "evidence"),
    [
        ("rain", {"wet": 1}),
        ("sprinkler", {"wet": 1}),
        ("cloudy", {"wet": 1, "sprinkler": 0}),
        ("wet", {}),
        ("rain", {"cloudy": 1, "wet": 0}),
        ("cloudy", {}),
    ],
)
def test_classical_network_equals_plain_bayes(query: str, evidence: dict[str, int]) -> None:
    expected = brute_force(query, evidence)
    for order in [(0, 1, 2, 3), (3, 2, 1, 0)]:
        net = sprinkler_net(order)
        np.testing.assert_allclose(net.posterior(query, evidence), expected, rtol=1e-13, atol=1e-15)
        # interference on with every pairwise cos = 0: the classical network again.
        if query != "rain":
            got = net.posterior(query, evidence, interference="explicit", theta=math.pi / 2)
            np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)


def test_network_evidence_by_state_name_and_joint_sums_to_one() -> None:
    net = sprinkler_net()
    np.testing.assert_allclose(net.posterior("rain", {"wet": "wet"}), net.posterior("rain", {"wet": 1}))
    assert net.joint().sum() == pytest.approx(1.0)
    assert net.variables.index("cloudy") < net.variables.index("wet")


def test_network_quantum_modes_sum_to_one() -> None:
    net = sprinkler_net()
    for kwargs in (
        {"interference": "phases"},
        {"interference": "heuristic"},
        {"interference": "explicit", "theta": 2.5},
    ):
        post = net.posterior("sprinkler", {"wet": 1}, **kwargs)
        assert post.sum() == pytest.approx(1.0)
        assert np.all((post >= 0) & (post <= 1))


def pd_net(theta: float = 0.0) -> QuantumLikeBayesNet:
    return QuantumLikeBayesNet(
        [
            Node("p1", ("D", "C"), np.array([0.5, 0.5]), phases=np.array([0.0, theta])),
            Node("p2", ("D", "C"), np.array([[0.97, 0.03], [0.84, 0.16]]), parents=("p1",)),
        ]
    )


@pytest.mark.parametrize("theta", [0.0, 1.0, math.pi / 2, 2.5, math.pi])
def test_network_amplitude_phases_match_expanded_formula(theta: float) -> None:
    # |psi(D, D) + psi(C, D) e^{i theta}|^2 = p1 + p2 + 2 sqrt(p1 p2) cos theta (Eq. 25 = Eq. 26).
    got = pd_net(theta).posterior("p2", interference="phases")
    assert got[0] == pytest.approx(disjunction_probability(0.97, 0.84, theta=theta), abs=1e-12)
    assert got.sum() == pytest.approx(1.0)


def test_network_heuristic_matches_disjunction() -> None:
    net = pd_net()
    assert net.posterior("p2", interference="heuristic", positive="D")[0] == pytest.approx(
        disjunction_probability(0.97, 0.84), abs=1e-12
    )
    assert net.posterior("p2")[0] == pytest.approx(0.905)
    assert net.posterior("p2", {"p1": "C"}, interference="heuristic")[0] == pytest.approx(0.84)


def test_network_validation_errors() -> None:
    with pytest.raises(ValueError, match=r"Node 'x'.*sum to 1"):
        Node("x", ("a", "b"), np.array([0.3, 0.3]))
    with pytest.raises(ValueError, match=r"Node 'x'.*shape"):
        Node("x", ("a", "b"), np.array([[0.3, 0.7]]))
    with pytest.raises(ValueError, match="unknown parent 'ghost'"):
        QuantumLikeBayesNet([Node("x", ("a", "b"), np.array([[0.3, 0.7]] * 2), parents=("ghost",))])
    y = Node("y", ("a", "b"), np.array([[0.3, 0.7]] * 2), parents=("z",))
    z = Node("z", ("a", "b"), np.array([[0.3, 0.7]] * 2), parents=("y",))
    with pytest.raises(ValueError, match="cycle"):
        QuantumLikeBayesNet([y, z])
    net = sprinkler_net()
    with pytest.raises(ValueError, match="no state 'soaked'"):
        net.posterior("rain", {"wet": "soaked"})
    with pytest.raises(ValueError, match="binary query"):
        net.posterior("rain", {"wet": 1}, interference="heuristic")
    with pytest.raises(ValueError, match="also given as evidence"):
        net.posterior("rain", {"rain": 0})
    with pytest.raises(ValueError, match="needs theta"):
        net.posterior("wet", interference="explicit")
    with pytest.raises(KeyError, match="unknown variable"):
        net.posterior("snow")


# --------------------------------------------------------------------------------------------------------
# Song et al. (2022), Case 1: crossing over two lane beliefs
# --------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("case", sorted(CASES))
def test_cbm_is_a_plane_and_matches_the_network(case: str) -> None:
    g = np.linspace(0.0, 1.0, 7)
    b1, b2 = np.meshgrid(g, g, indexing="ij")
    z = cbm_cross_probability(b1, b2, case)
    # additive CPT: z(b1, b2) = z(b1, 0) + z(0, b2) - z(0, 0)
    np.testing.assert_allclose(z, z[:, :1] + z[:1, :] - z[0, 0], atol=1e-12)
    for x, y in [(0.2, 0.9), (0.5, 0.5), (1.0, 0.3)]:
        assert crossing_network(x, y, case).posterior("cross")[0] == pytest.approx(
            float(cbm_cross_probability(x, y, case)), abs=1e-12
        )


@pytest.mark.parametrize("case", sorted(CASES))
def test_qlb_crossing_matches_network_and_collapses(case: str) -> None:
    for x, y in [(0.3, 0.7), (0.5, 0.5), (0.9, 0.15), (0.05, 0.6)]:
        cos = crossing_pair_cosines(x, y, case)
        net = crossing_network(x, y, case)
        expected = net.posterior("cross", interference="explicit", theta=np.arccos(cos))[0]
        assert float(qlb_cross_probability(x, y, case)) == pytest.approx(expected, abs=1e-12)
    g = np.linspace(0.0, 1.0, 21)
    b1, b2 = np.meshgrid(g, g, indexing="ij")
    cbm = cbm_cross_probability(b1, b2, case)
    np.testing.assert_allclose(qlb_cross_probability(b1, b2, case, theta=math.pi / 2), cbm, atol=1e-12)
    q = qlb_cross_probability(b1, b2, case)
    assert np.all((q >= 0.0) & (q <= 1.0))
    corners = (np.isin(b1, [0.0, 1.0])) & (np.isin(b2, [0.0, 1.0]))
    np.testing.assert_allclose(q[corners], cbm[corners], atol=1e-12)
    assert np.max(np.abs(q - cbm)) > 0.1  # interference bends the plane somewhere


@settings(max_examples=100, deadline=None)
@given(unit, unit, angle, angle)
def test_qlb_crossing_in_unit_interval_for_any_phases(b1: float, b2: float, t1: float, t2: float) -> None:
    for case in CASES:
        p = float(qlb_cross_probability(b1, b2, case, theta=(t1, t2)))
        assert 0.0 <= p <= 1.0
        # Kronecker interference keeps both scores non-negative: P(cross) + P(wait) = 1 with no clipping.
        p_col, q_col = qlb._crossing_columns(b1, b2, case)
        c1, c2 = math.cos(t1), math.cos(t2)
        assert qlb._kron_score(p_col, c1, c2) >= -1e-15
        assert qlb._kron_score(q_col, c1, c2) >= -1e-15


def test_crossing_vectorised_over_pedestrians() -> None:
    rng = np.random.default_rng(5)
    b1, b2 = rng.random((2, 200))
    out = qlb_cross_probability(b1, b2, "near")
    assert out.shape == (200,)
    np.testing.assert_allclose(out[17], qlb_cross_probability(b1[17], b2[17], "near"), atol=1e-15)
    t1, t2 = crossing_neutral_phases("mid")
    smooth = qlb_cross_probability(b1, b2, "mid", theta=(t1, t2))
    assert smooth.shape == (200,)
    assert cbm_cross_probability(b1, 0.5).shape == (200,)
    with pytest.raises(ValueError, match="unknown crossing case"):
        cbm_cross_probability(0.5, 0.5, "very near")
    with pytest.raises(ValueError, match="b2"):
        qlb_cross_probability(0.5, 1.5)


# --------------------------------------------------------------------------------------------------------
# Song et al. (2022), Case 2: force-intensity update
# --------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("base", [PED_PED_INTENSITY, VEHICLE_PED_INTENSITY])
def test_force_update_end_points_and_shape(base: float) -> None:
    cfg = ForceUpdateConfig()
    frac = np.linspace(0.0, 1.0, 101)
    qlb_curve = updated_force_intensity(base, frac)
    classical = classical_updated_force_intensity(base, frac)
    assert qlb_curve[0] == pytest.approx(base, abs=1e-12)
    assert qlb_curve[-1] == pytest.approx(base * (1 + cfg.gain), abs=1e-12)
    np.testing.assert_allclose(classical, base * (1 + cfg.gain * frac), atol=1e-12)
    assert np.max(np.abs(qlb_curve - classical)) > 0.05 * base  # bent, not the straight line
    assert np.all(qlb_curve >= 0.0)
    np.testing.assert_allclose(updated_force_intensity(base, frac, theta=math.pi / 2), classical, atol=1e-12)


def test_force_update_config_and_input_validation() -> None:
    assert (PED_PED_INTENSITY, VEHICLE_PED_INTENSITY) == (0.42, 0.71)
    assert 0.5 * math.pi <= ForceUpdateConfig().heuristic_phase() <= math.pi
    with pytest.raises(ValueError, match="hazard_given_irrational must exceed"):
        ForceUpdateConfig(hazard_given_rational=0.8, hazard_given_irrational=0.2)
    with pytest.raises(ValueError, match="gain"):
        ForceUpdateConfig(gain=-1.0)
    with pytest.raises(ValueError, match="irrational_fraction"):
        classical_updated_force_intensity(0.42, 1.5)
    with pytest.raises(ValueError, match="base intensity"):
        updated_force_intensity(-0.42, 0.5)
    out = updated_force_intensity(np.array([PED_PED_INTENSITY, VEHICLE_PED_INTENSITY]), np.array([0.3, 0.3]))
    assert out[1] / out[0] == pytest.approx(VEHICLE_PED_INTENSITY / PED_PED_INTENSITY)
