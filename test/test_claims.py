"""The one claims checker (issue 22): claims (a) to (d) on every valid system, every meeting.

The paper's theorem holds for every conservative rotor system with self-stable drives, so
the checker is tested on random valid systems (hypothesis), built from their linear pieces:
x = (q, z, qdot, zdot), M xdd + G xd + K x + diag(0, K_D) zd = 0 with M symmetric positive
definite, G skew (gyroscopic), K = diag(Hessian of the potential, K_S). The meetings are
checked against values computed here independently (the real-root count, bisected).
"""

import dataclasses
import math

from gyro_rotor.core.linearize import linearize
from gyro_rotor.core.params import RotorParams
from gyro_rotor.core.scene import load_scene
from gyro_rotor.core.steady import steady_motion
from gyro_rotor.linear import claims as cl
from gyro_rotor.linear.locus import check_claims as named_claims
from gyro_rotor.linear.system import check_claims, from_analytic, linearize_scene
from hypothesis import example, given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from random_systems import random_system_file


def pieces(M, G, K, K_S, K_D):
    """A0, B, C of the paper's form from the matrices of the linearized equations."""
    n, m = len(K), len(K_S)
    N = n + m
    Kf = np.zeros((N, N))
    Kf[:n, :n] = K
    Kf[n:, n:] = np.diag(K_S)
    Minv = np.linalg.inv(M)
    A0 = np.block([[np.zeros((N, N)), np.eye(N)], [-Minv @ Kf, -Minv @ G]])
    E = np.vstack([np.zeros((n, m)), np.eye(m)])
    B = np.vstack([np.zeros((N, m)), Minv @ E])
    C = np.hstack([np.zeros((m, N)), E.T])
    return cl.DriveSystem(A0=A0, B=B, C=C, K_scene=np.asarray(K_D, float))


def random_system(seed, n, m, indefinite=False):
    """Return a random valid system (module doc); ``indefinite``: a negative Hessian root."""
    rng = np.random.default_rng(seed)
    N = n + m

    def spd(k, lo, hi):
        Q, _ = np.linalg.qr(rng.normal(size=(k, k)))
        return Q @ np.diag(np.exp(rng.uniform(math.log(lo), math.log(hi), k))) @ Q.T
    M = spd(N, 0.2, 5.0)
    W = rng.normal(size=(N, N)) * rng.uniform(0.0, 20.0)
    G = W - W.T
    K = spd(n, 0.2, 50.0)
    if indefinite:
        w, V = np.linalg.eigh(K)
        w[0] = -w[0]
        K = V @ np.diag(w) @ V.T
    K_S = np.exp(rng.uniform(math.log(0.1), math.log(100.0), m))
    K_D = np.exp(rng.uniform(math.log(0.01), math.log(10.0), m))
    return pieces(M, G, K, K_S, K_D)


def n_real_near(A0, B, C, K, lam):
    """Real roots of A0 - K B C within |lam|/2 of ``lam``, as LAPACK returns them.

    A root small against ||A(K)|| is resolved through A(K)^-1 (Woodbury, written here
    independently of the checker): its reciprocal is then among the largest eigenvalues.
    """
    A = A0 - K * B @ C
    if abs(lam) ** 2 * 1e3 >= np.linalg.norm(A, 2) or np.linalg.cond(A0) > 1e12:
        roots = np.linalg.eigvals(A)
    else:
        A0i = np.linalg.inv(A0)
        X = A0i @ B
        Ai = A0i + X @ np.linalg.solve(np.eye(B.shape[1]) / K - C @ X, C @ A0i)
        mu = np.linalg.eigvals(Ai)
        roots = 1.0 / mu[np.abs(mu) > 0]
    near = roots[np.abs(roots - lam) < 0.5 * abs(lam)]
    return int(np.sum(near.imag == 0.0))


def bisect_meeting(sys, lo, hi, lam):
    """K where the real-root count near lam changes between lo and hi, by bisection."""
    A0, B, C = sys.locus_pieces()
    c_lo = n_real_near(A0, B, C, lo, lam)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if n_real_near(A0, B, C, mid, lam) == c_lo:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return 0.5 * (lo + hi)


# -- properties over random valid systems ------------------------------------------------------
# 100 examples fit about 90 s: an example costs 0.62 s of cpu, 0.72-0.87 s wall on the 2
# shared cores (load 4), after the checker's continuation kernels were made cheaper (1.34 s
# wall before: 300 examples took 403 s, then 216 s; 120 took 105 s).
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 4), m=st.integers(1, 3))
# a break-in and a breakaway 3e-8 K apart (a real root passing a complex pair as it lands,
# near a triple root): both were 'NOT verified' in the fixed window K* (1 -/+ 1e-7)
@example(seed=213, n=2, m=1)
def test_claims_hold_on_every_random_valid_system(seed, n, m):
    res = cl.check(random_system(seed, n, m))
    assert res.all_hold, {k: c.detail for k, c in res.claims.items()}
    assert res.claims['d'].data['net_meetings'] == m
    assert all(mt.verified and mt.lam < 0 for mt in res.meetings)
    assert res.K_D_star == sorted(res.K_D_star)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 4), m=st.integers(1, 3))
@example(seed=213, n=2, m=1)    # two meetings 3e-8 K apart: each in a window of 2.5e-8
def test_every_meeting_is_a_real_root_count_change(seed, n, m):
    """Each K* found changes the real-root count there (bisected independently) to 1e-10.

    Counted at K* (1 -/+ w), w the meeting's window (at most 1e-7): a window reaching the
    next meeting near lambda* would count that one's change too.
    """
    sys = random_system(seed, n, m)
    A0, B, C = sys.locus_pieces()
    for mt in cl.check(sys).meetings:
        w = mt.window
        assert 0 < w <= 1e-7
        below = n_real_near(A0, B, C, mt.K_D * (1 - w), mt.lam)
        above = n_real_near(A0, B, C, mt.K_D * (1 + w), mt.lam)
        assert above - below == 2 * mt.multiplicity * (
            1 if mt.kind is cl.MeetingKind.BREAK_IN else -1)
        K_ind = bisect_meeting(sys, mt.K_D * (1 - w), mt.K_D * (1 + w), mt.lam)
        assert abs(K_ind - mt.K_D) <= 1e-10 * mt.K_D


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 4), m=st.integers(1, 3))
def test_an_indefinite_potential_fails_a_or_b(seed, n, m):
    """The checker can fail: a Hessian with a negative eigenvalue breaks the theorem."""
    res = cl.check(random_system(seed, n, m, indefinite=True))
    assert not (res.claims['a'].holds and res.claims['b'].holds)


def _doubled(sys, tweak=0.0):
    """Two uncoupled copies of ``sys`` (the second's A0 scaled by 1 + tweak)."""
    from scipy.linalg import block_diag
    return cl.DriveSystem(A0=block_diag(sys.A0, (1 + tweak) * sys.A0),
                          B=block_diag(sys.B, sys.B), C=block_diag(sys.C, sys.C),
                          K_scene=np.concatenate([sys.K_scene, sys.K_scene]))


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 2), m=st.integers(1, 2))
# a break-in and a breakaway 3e-8 K apart: the pair nearest the first at K* (1 + 1e-7) was
# two copies of one real root (the other copy's), not the pair; net 3 against the count's 2
@example(seed=213, n=2, m=1)
def test_two_identical_uncoupled_parts_meet_the_axis_in_pairs(seed, n, m):
    """Adversarial finding: two equal rotors on equal carriers keep every root double.

    The continuation stalled on the double roots (a step bounded by a gap of 0: h down to
    1e-14 for 200000 steps, 107 s) and judged (c) and (d) where it stopped, at K = 2e-7:
    both FAIL, no K_D*. The doubled system has the single one's K_D*, each met by two pairs.
    """
    one = cl.check(random_system(seed, n, m))
    two = cl.check(_doubled(random_system(seed, n, m)))
    assert two.all_hold, {k: c.detail for k, c in two.claims.items()}
    assert two.claims['d'].data['net_meetings'] == 2 * m
    assert [mt.multiplicity for mt in two.meetings] == [2] * len(one.meetings)
    assert np.allclose(two.K_D_star, one.K_D_star, rtol=1e-8)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 2), m=st.integers(1, 2),
       tweak=st.sampled_from([1e-6, 1e-4, 1e-2]))
def test_nearly_identical_parts_are_followed_to_the_regime(seed, n, m, tweak):
    """Nearly equal roots that move together do not stall the continuation.

    Adversarial finding: a carrier stiffness 10.5 against 10 kept the two fast roots (and
    the two slow ones) 4e-6 of their size apart for every K; a step bounded by a quarter of
    that gap took 200000 steps to K = 9.5 (8 min) and (c) was judged there: FAIL.
    """
    res = cl.check(_doubled(random_system(seed, n, m), tweak))
    assert res.all_hold, {k: c.detail for k, c in res.claims.items()}
    assert res.claims['d'].data['net_meetings'] == 2 * m
    assert len(res.locus.K) < 20000


def test_slow_roots_near_zero_still_count_as_real():
    """Issue 22: the slow roots -K_S/K_D fell below a magnitude threshold and dropped out."""
    sys = random_system(7, 2, 3)
    res = cl.check(sys)
    loc = res.locus
    assert loc.real_counts[-1] == 2 * 3
    lam = loc.roots[-1]
    slow = np.sort(np.abs(lam[lam.imag == 0]))[:3]
    assert np.all(slow < 1e-6 * np.abs(lam).max())


# -- a bubble narrower than any grid ---------------------------------------------------------
def bubble_system(eps):
    """Two nearly independent drives: drive 1's fast root passes drive 2's slow root.

    Each half: a carrier coordinate x_i (spring k_i) and a rotor z_i coupled through the
    mass matrix; eps couples the two rotors' inertias. At eps = 0 the two real roots cross;
    for small eps they meet, leave the axis and come back (a breakaway, then a break-in).
    """
    M = np.array([[1.0, 0.0, 0.3, 0.0],
                  [0.0, 1.0, 0.0, 0.3],
                  [0.3, 0.0, 0.5, eps],
                  [0.0, 0.3, eps, 2.0]])
    G = np.zeros((4, 4))
    return pieces(M, G, np.diag([4.0, 9.0]), [30.0, 1.0], [0.1, 0.1])


def test_a_bubble_narrower_than_1e_4_is_found_both_ends_with_kinds():
    sys = bubble_system(2e-6)
    res = cl.check(sys)
    assert res.all_hold, {k: c.detail for k, c in res.claims.items()}
    kinds = [mt.kind for mt in res.meetings]
    # two break-ins (one per drive) and the bubble: a breakaway, then a break-in
    assert kinds.count(cl.MeetingKind.BREAK_IN) == 3
    assert kinds.count(cl.MeetingKind.BREAKAWAY) == 1
    i = kinds.index(cl.MeetingKind.BREAKAWAY)
    away, back = res.meetings[i], res.meetings[i + 1]
    assert back.kind is cl.MeetingKind.BREAK_IN
    width = (back.K_D - away.K_D) / away.K_D
    assert 0 < width < 1e-5
    # a 481-point geometric grid over the same range has no point inside the bubble
    K_lo, K_hi = res.locus.K[0], res.locus.K[-1]
    grid = np.geomspace(K_lo, K_hi, 481)
    assert not np.any((grid > away.K_D) & (grid < back.K_D))
    # both ends independently: the real-root count bisected
    for mt in (away, back):
        K_ind = bisect_meeting(sys, mt.K_D * (1 - 0.2 * width), mt.K_D * (1 + 0.2 * width),
                               mt.lam)
        assert abs(K_ind - mt.K_D) <= 1e-10 * mt.K_D
    assert res.claims['d'].data['net_meetings'] == 2


# -- the centrifuge: the quaternion model and its system file agree ------------------------------
CENTRIFUGE_SETS = [
    {},
    {'A_R': 0.02, 'A_M': 0.03, 'C_R': 0.03, 'C_M': 0.01, 'G': 98.1, 's': 0.05,
     'c_theta': 50.0, 'c_psi': 20.0, 'K_S': 10.0, 'K_D': 0.05},
    {'A_R': 0.08, 'A_M': 0.05, 'C_R': 0.015, 'C_M': 0.02, 'G': 50.0, 's': 0.1,
     'c_theta': 30.0, 'c_psi': 40.0, 'K_S': 50.0, 'K_D': 0.3},
    {'A_R': 0.04, 'A_M': 0.12, 'C_R': 0.025, 'C_M': 0.005, 'G': 120.0, 's': 0.02,
     'c_theta': 80.0, 'c_psi': 10.0, 'K_S': 5.0, 'K_D': 0.02},
]


@pytest.mark.parametrize('values', CENTRIFUGE_SETS, ids=['shipped', 'set1', 'set2', 'set3'])
def test_centrifuge_K_D_star_same_from_quaternion_model_and_system_file(values):
    p = RotorParams().replace(**values)
    sm = steady_motion(p, 0.1, 1)
    ref = named_claims(from_analytic(linearize(p, sm)))
    assert ref.all_hold, {k: c.detail for k, c in ref.claims.items()}
    consts = {f'constants.{k}': v for k, v in values.items() if k not in ('K_S', 'K_D')}
    drive = {f'drive.R.{k}': v for k, v in values.items() if k in ('K_S', 'K_D')}
    qdot = [0.0, sm.psidot0, sm.phi_M_dot0]
    scene = load_scene('centrifuge_euler', overrides={
        **consts, **drive, 'drive.R.Omega0': p.Omega0, 'steady.q': [0.1, 0.0, 0.0],
        'steady.qdot': qdot})
    res = check_claims(linearize_scene(scene))
    assert res.all_hold, {k: c.detail for k, c in res.claims.items()}
    assert len(res.meetings) == len(ref.meetings) >= 1
    for a, b in zip(res.meetings, ref.meetings):
        assert a.kind is b.kind
        assert abs(a.K_D - b.K_D) <= 1e-10 * b.K_D
        assert abs(a.lam - b.lam) <= 1e-8 * abs(b.lam)


@pytest.mark.parametrize('scene', ['precession', 'nutation', 'stiff_drive', 'fast_spin',
                                   'pole_slip', 'upright', 'conservative', 'locked_housing'])
def test_one_checker_on_every_centrifuge_scene(scene):
    sc = load_scene(scene)
    lin = linearize(sc.system.params, sc.system.steady(), sc.system.model)
    cr = named_claims(from_analytic(lin))
    res = cl.check(from_analytic(lin).drive_system())
    held = {k: c.holds for k, c in res.claims.items()}
    assert {k: c.holds for k, c in cr.claims.items()} == held
    assert [mt.K_D for mt in cr.meetings] == res.K_D_star


# -- end to end: random systems written as system files ------------------------------------------
@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 2), m=st.integers(1, 2))
def test_random_system_files_end_to_end(seed, n, m, tmp_path_factory):
    """Through the system-file parser, code generation and linearization: (a)-(d) hold."""
    import yaml
    folder = tmp_path_factory.mktemp('sys')
    (folder / 'sys.yaml').write_text(yaml.safe_dump(random_system_file(seed, n, m)))
    (folder / 'scene.yaml').write_text(yaml.safe_dump(
        {'/**': {'ros__parameters': {'system': 'sys.yaml', 't_end': 1.0}}}))
    lin = linearize_scene(load_scene(str(folder / 'scene.yaml')))
    res = check_claims(lin)
    assert res.all_hold, {k: c.detail for k, c in res.claims.items()}
    assert res.claims['d'].data['net_meetings'] == m


def test_a_weakly_reached_mode_is_resolved_against_the_datas_own_round_off():
    """Found by hypothesis: a slow mode (0.008 rad/s) the drive reaches only weakly.

    Its damping at the scene's K_D, -6.6e-13 1/s, lies below the double-precision
    resolution of A(K) (1.1e-11) but far beyond the round-off of A0 itself (the real parts
    of its K = 0 roots, 3.5e-15): (b) holds. Shifted right by 1e-12 (claim (a) cannot see
    it, within the resolution) the same root is at +3.4e-13: (b) fails.
    """
    sys = random_system(174451358, 3, 1)
    res = cl.check(sys)
    assert res.all_hold, {k: c.detail for k, c in res.claims.items()}
    assert 'damped below the double-precision resolution' in res.claims['b'].detail
    assert -1e-12 < res.claims['b'].data['max_re_reached'] < 0
    shifted = cl.DriveSystem(sys.A0 + 1e-12 * np.eye(len(sys.A0)), sys.B, sys.C, sys.K_scene)
    res = cl.check(shifted)
    assert res.claims['a'].holds and not res.claims['b'].holds
    assert res.claims['b'].data['failing']


def test_claim_b_headline_names_the_K_D_it_was_judged_at():
    # the scene 'conservative' has K_D = 0: (b) is judged at a substituted small K_D, and
    # its headline says so instead of "at the scene's K_D"
    from gyro_rotor.core.scene import load_scene
    b = check_claims(linearize_scene(load_scene('conservative'))).claims['b']
    assert "at the scene's K_D" not in b.statement
    assert 'K_D = 0 substituted' in b.statement and 'at K_D = 0.00045' in b.statement
    b = check_claims(linearize_scene(load_scene('precession'))).claims['b']
    assert b.statement.startswith("at the scene's K_D every root")


# -- reach independent of the scale of K_S (review finding 1) ----------------------------------
@pytest.mark.parametrize('scene, K_S, fixed', [
    ('precession', 1e4, 1), ('precession', 5e4, 1), ('precession', 1e5, 1),
    ('centrifuge_euler', 3e4, 2), ('twin_gimbal', 1e5, 0), ('upright', 5e4, 4)])
def test_a_weakly_reached_mode_stays_reached_at_a_large_K_S(scene, K_S, fixed):
    """A stiff drive reaches the slow modes weakly (|C v| ~ 1/K_S), never not at all.

    At K_S = 5e4 the nutation of the precession scene has dRe/dK_D = -6.4e-10 (its
    eigenvector's zdot part 1.3e-6 in 40 digits): it was put on the fixed subspace
    because the staircase's rank cut-off grew with ||A0|| ~ K_S / C_R. What stays fixed:
    the structural zero root (cyclic psi; the system file's centrifuge keeps psi itself
    too: 2) and, around I (upright), the four tilt roots, exactly unreached whatever K_S.
    """
    ds = linearize_scene(load_scene(scene, overrides={'K_S': K_S})).drive_system()
    assert cl.fixed_subspace(ds.A0, ds.C).shape[1] == fixed


@pytest.mark.parametrize('scene, K_S', [('precession', 5e4), ('precession', 1e5),
                                        ('upright', 5e4)])
def test_claim_b_at_a_large_K_S_damps_every_reached_root(scene, K_S):
    res = cl.check(linearize_scene(load_scene(scene, overrides={'K_S': K_S})).drive_system())
    assert res.claims['b'].holds, res.claims['b'].detail
    assert res.claims['b'].data['unreached'] == (4 if scene == 'upright' else 0)
    assert res.all_hold, {k: c.detail for k, c in res.claims.items()}


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 4), m=st.integers(1, 3),
       scale=st.sampled_from([1e3, 1e5, 1e7]))
def test_every_mode_of_a_random_system_stays_reached_at_a_large_K_S(seed, n, m, scale):
    """A random system has no unreached mode (probability 1), at any drive stiffness.

    The same system with every K_S times ``scale``: ||A0|| grows with it, the reach of the
    slow modes shrinks like 1/K_S, and the fixed subspace stays empty.
    """
    sys = random_system(seed, n, m)
    N = n + m
    A0 = sys.A0.copy()
    # K_S enters A0 only as the columns of the rotor angles z in the block (rates,
    # positions), -M^-1 diag(0, K_S): scaling them scales every K_S
    A0[N:, n:N] *= scale
    assert cl.fixed_subspace(sys.A0, sys.C).shape[1] == 0
    assert cl.fixed_subspace(A0, sys.C).shape[1] == 0


def test_the_two_centrifuges_agree_on_reach_at_a_large_K_S():
    a = linearize_scene(load_scene('precession', overrides={'K_S': 3e4})).drive_system()
    b = linearize_scene(load_scene('centrifuge_euler', overrides={'K_S': 3e4})).drive_system()
    assert cl.check(a).claims['b'].data['unreached'] == 0
    assert cl.check(b).claims['b'].data['unreached'] == 0


def test_fixed_subspace_decision_does_not_depend_on_the_working_precision():
    """The exact zeros of the staircase are zeros of the data: 30 and 50 digits agree."""
    for scene, K_S in (('upright', 5e4), ('precession', 1e5)):
        ds = linearize_scene(load_scene(scene, overrides={'K_S': K_S})).drive_system()
        dims = []
        for dps in (30, 50):
            old = cl.FINE_DPS
            cl.FINE_DPS = dps
            try:
                dims.append(cl.fixed_subspace(ds.A0, ds.C).shape[1])
            finally:
                cl.FINE_DPS = old
        assert dims[0] == dims[1] == cl.fixed_subspace(ds.A0, ds.C).shape[1]


# -- nearly symmetric drives, K_S = 0 (review findings 3, 4) ------------------------------------
def halves_system(tmp_path, mass_off='0.05', g2='0.6'):
    """Two 1-DOF halves (x, y), each with its drive; coupled by an off-diagonal mass."""
    import yaml
    (tmp_path / 'sys.yaml').write_text(yaml.safe_dump({
        'name': 'halves', 'coordinates': ['x', 'y'], 'rotors': ['R1', 'R2'], 'constants': {},
        'mass_matrix': [['1.0', mass_off], [mass_off, '1.0']],
        'rotor_inertia': ['0.05', '0.05'], 'guidance': [['0.5', '0'], ['0', g2]],
        'potential': '10*x**2/2 + 10*y**2/2',
        'drives': [{'K_S': 5.0, 'K_D': 0.1, 'Omega0': 100.0}] * 2}))
    (tmp_path / 'scene.yaml').write_text(yaml.safe_dump(
        {'/**': {'ros__parameters': {'system': 'sys.yaml', 't_end': 1.0}}}))
    return linearize_scene(load_scene(str(tmp_path / 'scene.yaml'))).drive_system()


def test_nearly_equal_drives_reach_the_asymptotic_regime_at_a_finite_K(tmp_path):
    """Finding 3: two slow roots -K_S/(K g) of nearly equal drives differ by round-off.

    Their gap's ratio over a decade was required to be 0.1 though the gap is round-off:
    the asymptotic regime was never found, the end of the locus grew to K = 1e17 where
    A(K)^-1 has exact zero eigenvalues and the assignment crashed ("cost matrix is
    infeasible"). A gap within round-off at both K is a persistent double root.
    """
    import warnings
    sys = halves_system(tmp_path)
    A0l, Bl, Cl = sys.locus_pieces()
    _, V = cl.split(A0l, Cl)
    R = cl._Roots(V.T @ A0l @ V, V.T @ Bl, Cl @ V)
    K_ref = 0.5
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        lo, hi = cl._ends(R, K_ref)
    assert hi == 1e4 * K_ref


@pytest.mark.parametrize('seed, n, frac', [(103, 2, 1e-3), (31, 2, 0.1), (138, 1, 0.9),
                                           (63, 2, 1.0)])
def test_below_K_inv_the_floor_is_the_round_off_of_A_K(seed, n, frac):
    """Finding: the floor was min(||A||, ||A^-1|| |lambda|^2) where only A(K) was used.

    At or below K_inv every root is A(K)'s (:meth:`_Roots.forms`) and a slow one's error
    is eps ||A(K)||'s: the slowest root's, against 50 digits, was 0.04 to 0.14 eps ||A(K)||
    on one machine, 0.009 to 0.22 on another (AMD EPYC, AVX-512: LAPACK's kernels differ,
    and so does the round-off, not its scale), and 1.2e2 to 4.8e3 eps ||A^-1|| |lambda|^2
    (seed 103, K = 1e-3 K_inv). Asserted: the error within three decades below one
    eps ||A(K)||, the backward-stable scale (the band 0.01 .. 0.2 of one machine's figures
    failed on the other), and over 100 eps ||A^-1|| |lambda|^2 where that scale is at least
    four decades below eps ||A(K)|| (seeds 103, 138, 63: 2.5e4, 2.1e4, 6.4e4; seed 31's
    3.3e3 is too close to tell within the band). Above K_inv the roots taken from A(K)^-1
    have its bound.
    """
    import mpmath
    from scipy.optimize import linear_sum_assignment
    eps = np.finfo(float).eps
    A0l, Bl, Cl = random_system(seed, n, 2).locus_pieces()
    _, V = cl.split(A0l, Cl)
    R = cl._Roots(V.T @ A0l @ V, V.T @ Bl, Cl @ V)
    K = frac * R.K_inv
    lam = R(K, vectors=False)[0]
    with mpmath.workdps(50):
        exact = mpmath.eig(mpmath.matrix(R.A(K).tolist()))[0]
    exact = np.array([complex(z) for z in exact])
    r, c = linear_sum_assignment(np.abs(lam[:, None] - exact[None, :]))
    s = np.argmin(np.abs(exact[c]))
    err = abs(lam[r[s]] - exact[c[s]])
    floor = cl._floor(R, K, lam)
    assert np.all(floor == 1e4 * eps * cl._norm2(R.A(K)))
    assert 1e-3 * floor[r[s]] / 1e4 < err <= floor[r[s]] / 1e4
    # not the A^-1 scale: decidable where the two scales are at least four decades apart
    # (seed 31's are 3.5: its error 117 times the A^-1 scale on one CPU, 0.036 eps ||A(K)||,
    # would be 33 times at the band's measured 0.01)
    inverse_scale = eps * cl._norm2(R._inverse(K)) * abs(exact[c[s]]) ** 2
    if floor[r[s]] / 1e4 >= 1e4 * inverse_scale:
        assert err > 100 * inverse_scale
    K = 10 * R.K_inv
    lam, (A, Ai) = R(K, vectors=False)[0], R.forms(K)
    mu = np.linalg.eigvals(A)
    inv = lam != mu[np.argmin(np.abs(lam[:, None] - mu[None, :]), axis=1)]
    assert inv.any()
    assert np.all(cl._floor(R, K, lam)[inv] == 1e4 * eps * (cl._norm2(Ai) * np.abs(lam[inv]) ** 2))


def test_a_drive_without_stiffness_makes_c_and_d_not_applicable():
    """Finding 4: K_S = 0 on drive R2 is outside the theorem: (c), (d) say so, no K_D*."""
    from gyro_rotor.cli.util import load_scene_with_sets
    lin = linearize_scene(load_scene_with_sets('twin_gimbal', ['drive.R2.K_S=0']))
    ds = lin.drive_system()
    assert cl.cyclic_drives(ds.A0, ds.C) == [1]
    res = cl.check(ds)
    for key in 'cd':
        c = res.claims[key]
        assert not c.applicable and not c.holds
        assert c.detail.startswith('not applicable: K_S = 0 on drive(s) #2')
    assert res.meetings == () and res.claims['a'].applicable
    ds = linearize_scene(load_scene('twin_gimbal')).drive_system()
    assert cl.cyclic_drives(ds.A0, ds.C) == []


def test_claim_d_counts_an_unverified_event_as_net_0_and_the_real_count_decides():
    """An unverified event is net 0; the verified net must equal m and the real count.

    Its kind is a guess and is not counted. Found by hypothesis
    (test_nearly_identical_parts_are_followed_to_the_regime, seed 69, n = m = 2, tweak
    1e-2): two real roots touch at -0.23025 and at -0.22532 1/s (a double root at K_D* that
    stays real on both sides: 2.5e-5 apart at K_D* (1 -/+ 1e-5), real at every window down
    to round-off); (d) failed on them although the verified net (4), the real count (net 4)
    and m = 4 agreed.
    """
    meetings = (cl.Meeting(K_D=2.0, lam=-3.0, kind=cl.MeetingKind.BREAK_IN, verified=True),
                cl.Meeting(K_D=5.0, lam=-1.0, kind=cl.MeetingKind.BREAK_IN, verified=False))
    loc = cl.Locus(K=np.array([1.0, 10.0]), roots=np.zeros((2, 4), complex), meetings=meetings,
                   real_counts=(0, 4))
    d = cl._claim_d(loc, 2)             # the real count says 2, the verified net 1: FAIL
    assert d.data['net_meetings'] == 1 and d.data['unverified_pairs'] == 1
    assert not d.holds and '1 pair(s) at events NOT verified' in d.detail
    d = cl._claim_d(dataclasses.replace(loc, real_counts=(0, 2)), 1)
    assert d.holds and 'unresolved event at K_D* = 5' in d.detail       # net 0: holds
    d = cl._claim_d(dataclasses.replace(loc, real_counts=(0, 2)), 2)
    assert not d.holds                                                  # m = 2: FAIL
    verified = dataclasses.replace(meetings[1], verified=True)
    d = cl._claim_d(dataclasses.replace(loc, meetings=(meetings[0], verified)), 2)
    assert d.holds and d.data['net_meetings'] == 2 and d.data['unverified_pairs'] == 0


def test_claims_hold_on_nearly_identical_parts_with_touching_real_roots():
    """The hypothesis example (seed 69, n = m = 2, tweak 1e-2), kept as a case."""
    res = cl.check(_doubled(random_system(69, 2, 2), 1e-2))
    assert res.all_hold, {k: c.detail for k, c in res.claims.items()}
    assert res.claims['d'].data['net_meetings'] == 4 == res.claims['d'].data['net_from_counts']
