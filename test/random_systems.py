"""Random valid system files for the property tests (the paper's claims hold for all of them).

Constant mass matrix and guidance, a quadratic potential with a positive definite Hessian,
self-stable drives: a conservative rotor system with m synchronous drives (sections 2-3).
"""

import numpy as np


def random_system_file(seed: int, n: int, m: int, *, zero_K_S: bool = False) -> dict:
    """Return a random valid system file of n coordinates and m rotors.

    With ``zero_K_S``, K_S = 0 on a random nonempty set of drives (the rotor angle cyclic).
    """
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    M = Q @ np.diag(rng.uniform(0.5, 3.0, n)) @ Q.T
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    H = Q @ np.diag(rng.uniform(1.0, 30.0, n)) @ Q.T
    q = [f'q{i}' for i in range(n)]
    zero = np.zeros(m, dtype=bool)
    if zero_K_S:
        zero = rng.random(m) < 0.5
        zero[rng.integers(m)] = True
    return {
        'name': f'{"jordan" if zero_K_S else "random"}{seed}', 'coordinates': q,
        'rotors': [f'R{k}' for k in range(m)],
        'constants': {}, 'mass_matrix': [[repr(float(x)) for x in row] for row in M],
        'rotor_inertia': [repr(float(x)) for x in rng.uniform(0.01, 0.1, m)],
        'guidance': [[repr(float(x)) for x in row] for row in rng.uniform(-1, 1, (m, n))],
        'potential': ' + '.join(f'({float(H[i, j])!r})*{q[i]}*{q[j]}/2'
                                for i in range(n) for j in range(n)),
        'drives': [{'K_S': 0.0 if zero[k] else float(rng.uniform(1, 20)),
                    'K_D': float(rng.uniform(0.01, 1)), 'Omega0': float(rng.uniform(50, 300))}
                   for k in range(m)]}


def unstable_scene(folder, t_end: float = 10.0) -> str:
    """Write a statically unstable system (V = k x^2 / 2, k < 0) and its scene; its path.

    Outside the theorem's premise (V not positive definite): the motion grows like
    exp(10 t) with the energy identity sound (the residual 1e-11 of |E*|).
    """
    (folder / 'one_neg.yaml').write_text(
        'name: one\ncoordinates: [x]\nrotors: [R]\nconstants: {J: 0.1, C: 0.01, k: -10.0}\n'
        'mass_matrix:\n  - ["J"]\nrotor_inertia: ["C"]\nguidance: [["1"]]\n'
        'potential: "k*x**2/2"\n'
        'drives:\n  - {K_S: 5.0, K_D: 0.01, Omega0: 100.0, pole_pairs: 0}\n')
    (folder / 'sc_neg.yaml').write_text(
        f'/**:\n  ros__parameters:\n    system: one_neg.yaml\n    t_end: {t_end!r}\n'
        '    initial: {q: [0.01], qdot: [0.0], z: [0.0], zdot: [0.1]}\n')
    return str(folder / 'sc_neg.yaml')
