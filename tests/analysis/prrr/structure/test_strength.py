"""analysis.prrr.structure.strength: section stresses against beam theory, the rated load cases, safety
factors read from the material, and an optimum that cannot fall below the problem's safety factor."""

from __future__ import annotations

import dataclasses as dc
import math

import numpy as np
import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.structure import frame_model as fm
from hapticopt.analysis.prrr.structure import strength as S
from hapticopt.analysis.prrr.structure.frame_beam import Section, beam_end_forces, beam_global_stiffness
from hapticopt.design import io, materials
from hapticopt.design.prrr.params import with_material

# a 6061-T6 bar b × t (local y × z), L long
E, NU = 68.9e9, 0.33
B, T, L = 0.020, 0.010, 0.200
SEC = Section(B, T, E, NU)


def _solve(nodes: np.ndarray, fixed: list[int], load_node: int, load: np.ndarray):
    """A straight beam x along global x (elements between consecutive ``nodes``), clamped at ``fixed``
    nodes, a force ``load`` (3,) [N] at ``load_node``: each element's end forces (local, 12)."""
    n = len(nodes)
    K = np.zeros((6 * n, 6 * n))
    zref = np.array([0.0, 0.0, 1.0])
    for e in range(n - 1):
        k = beam_global_stiffness(nodes[e], nodes[e + 1], zref, SEC, xp=np)
        idx = np.r_[6 * e:6 * e + 12]
        K[np.ix_(idx, idx)] += k
    free = np.array([i for i in range(6 * n) if i // 6 not in fixed])
    F = np.zeros(6 * n)
    F[6 * load_node:6 * load_node + 3] = load
    u = np.zeros(6 * n)
    u[free] = np.linalg.solve(K[np.ix_(free, free)], F[free])
    out = []
    for e in range(n - 1):
        d = u[6 * e:6 * e + 12][:, None]
        out.append(beam_end_forces(nodes[e], nodes[e + 1], zref, SEC, d=d, xp=np)[:, 0])
    return out


def test_cantilever_root_stress_is_PLc_over_I():
    """Tip force P along y: root moment M = PL about local z, σ = M (b/2)/I_z = 6PL/(t b²) (beam theory);
    the von Mises value adds the shear 1.5P/A (√(1 + 3(b/4L)²) − 1 = 0.09 % here)."""
    P = 100.0
    f = _solve(np.array([[0.0, 0, 0], [L, 0, 0]]), [0], 1, np.array([0.0, P, 0.0]))[0]
    assert abs(f[5]) == pytest.approx(P * L, rel=1e-9)  # M_z at the root
    assert abs(f[1]) == pytest.approx(P, rel=1e-9)
    sigma = 6.0 * P * L / (T * B**2)
    vm = S.rect_von_mises(f[None, :6, None], np.array([B]), np.array([T]))[0, 0]
    assert vm == pytest.approx(sigma, rel=0.01)
    # bending about the thin axis (force along z): σ = 6PL/(b t²)
    f = _solve(np.array([[0.0, 0, 0], [L, 0, 0]]), [0], 1, np.array([0.0, 0.0, P]))[0]
    vm = S.rect_von_mises(f[None, :6, None], np.array([B]), np.array([T]))[0, 0]
    assert vm == pytest.approx(6.0 * P * L / (B * T**2), rel=0.01)


def test_clamped_beam_with_a_central_load():
    """Clamped-clamped beam, central force P: M = PL/8 at the ends and the centre (Roark Table 8.1 case
    1c), σ = (PL/8)(b/2)/I_z; the shear P/2 adds √(1 + 3(b/L)²) − 1 = 0.37 % to von Mises at L/b = 20
    (the combination of the maxima is conservative: 1.5 % at L/b = 10)."""
    P, L = 100.0, 0.400
    nodes = np.array([[0.0, 0, 0], [L / 2, 0, 0], [L, 0, 0]])
    fs = _solve(nodes, [0, 2], 1, np.array([0.0, P, 0.0]))
    sigma = (P * L / 8.0) * (B / 2) / (T * B**3 / 12.0)
    for f in fs:
        assert abs(f[5]) == pytest.approx(P * L / 8.0, rel=1e-9) and abs(f[11]) == pytest.approx(P * L / 8.0, rel=1e-9)
        for end in (f[:6], f[6:]):
            vm = S.rect_von_mises(end[None, :, None], np.array([B]), np.array([T]))[0, 0]
            assert vm == pytest.approx(sigma, rel=0.01)


def test_pin_stress_closed_forms():
    """A pin along w = e_z: bending M alone gives 32M/(πd³); shear V alone 4V/(3A)·√3; an axial force
    N/A (the solid-circle formulas of the module docstring)."""
    d = 0.008
    w = np.array([0.0, 0.0, 1.0])
    f = np.zeros((6, 3))
    f[3, 0] = 2.0  # M about x
    f[0, 1] = 50.0  # V along x (gap 0: no extra moment)
    f[2, 2] = 30.0  # axial
    vm = S.pin_von_mises(f, w, d, 0.0)
    A = math.pi * d**2 / 4
    np.testing.assert_allclose(vm, [32 * 2.0 / (math.pi * d**3), math.sqrt(3) * 4 * 50.0 / (3 * A), 30.0 / A],
                               rtol=1e-12)


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def test_load_cases_are_the_rated_force_with_own_weight(paper):
    force = S.rated_force(paper)
    # seed 002 Table 1 / digest: F_x 1378, F_y 1194, F_z 3581 N at β = 60°
    np.testing.assert_allclose(force, [1378.3, 1193.7, 3581.0], rtol=1e-4)
    W, labels = S.load_cases(paper, force, 0.058)
    weight = -0.66 * S.GRAVITY  # seed 002 Table 4: M = 0.66 kg
    np.testing.assert_allclose(W[:, 0], [force[0], 0, weight, 0, 0.058 * force[0], 0])
    np.testing.assert_allclose(W[:, 5], [0, 0, -force[2] + weight, 0, 0, 0])
    assert labels[0].startswith("+x 1378 N") and labels[5].startswith("-z 3581 N")


def test_poses_home_at_draft_and_the_workspace_rim_above(paper):
    assert S.poses(paper, Fidelity.DRAFT).tolist() == [[0.0, 0.0, 0.0]]
    P = S.poses(paper, Fidelity.STANDARD)
    assert len(P) == 9
    np.testing.assert_allclose(np.hypot(P[1:7, 0], P[1:7, 1]), 0.070)  # φ140 mm (seed 002 Table 1)
    np.testing.assert_allclose(np.abs(P[7:, 2]), 0.0445)  # 89 mm high


def test_safety_factors_read_the_material_and_name_the_governing_part(paper):
    al = S.evaluate(paper, fidelity=Fidelity.DRAFT).metrics()
    hard = S.evaluate(with_material(paper, "7075-T6"), fidelity=Fidelity.DRAFT).metrics()
    # one material throughout: the frame's stresses do not depend on E (same ν), so SF ∝ yield
    assert hard["safety_factor_yield"] / al["safety_factor_yield"] == pytest.approx(503.0 / 276.0, rel=1e-9)
    m = materials.material("6061-T6")
    assert al["safety_factor_yield"] == pytest.approx(m.yield_strength / (al["strength_max_von_mises_MPa"] * 1e6))
    assert al["safety_factor_fatigue"] == pytest.approx(al["safety_factor_yield"] * 96.5 / 276.0)
    per_part = al["safety_factor_yield_per_part"]
    assert min(per_part.values()) == al["safety_factor_yield"]
    assert al["strength_governing_part"] == min(per_part, key=per_part.get)
    assert {f"{p}_{i}" for p in ("link1", "link2", "carriage", "pin_r1", "pin_r2", "pin_r3") for i in (1, 2, 3)} | {
        "platform"} == set(per_part)


def test_standard_checks_more_poses_and_is_no_safer(paper):
    d = S.evaluate(paper, fidelity=Fidelity.DRAFT).metrics()
    s = S.evaluate(paper, fidelity=Fidelity.STANDARD).metrics()
    assert s["safety_factor_yield"] <= d["safety_factor_yield"]
    assert s["strength_poses_unreachable"] == 0


def test_frame_stress_scales_linearly_with_the_force(paper):
    fp = fm.frame_params_of(paper, xp=np)
    W = np.zeros((6, 2))
    W[0, 0], W[4, 0] = 1.0, 0.058
    W[:, 1] = 7.0 * W[:, 0]
    parts, ok = S.part_stresses(fp, np.zeros(3), W)
    assert ok
    for v in parts.values():
        assert v[1] == pytest.approx(7.0 * v[0], rel=1e-9)


def test_an_optimum_cannot_fall_below_the_problem_safety_factor(tmp_path, paper):
    """Minimising the links' mass thins them (link_thickness_mm at its lower bound, 2.5 mm, when
    unconstrained); with safety_factor_yield ≥ 2 the optimum stops where the safety factor reaches 2.
    The base design's actuator force is lowered to 40 N (rated force 46 N along x) so that 10 mm links
    are feasible."""
    from hapticopt.optim import driver
    from hapticopt.optim.problem import problem_from_dict

    base = dc.replace(paper, actuator=dc.replace(paper.actuator, force_limit=40.0))
    path = tmp_path / "light.toml"
    io.save_design(base, path)

    def problem(constrained: bool):
        d = {"name": "thin", "base_file": str(path),
             "variables": [{"key": "structure.link_thickness_mm", "lower": 2.5, "upper": 12.0}],
             "objective": {"metric": "device_mass_links_kg", "sense": "minimise"},
             "optimiser": {"algorithm": "LN_COBYLA", "starts": 1, "seed": 0, "xtol_rel": 1e-4, "ftol_rel": 0.0,
                           "max_evals": 40}}
        if constrained:
            d["constraints"] = [{"metric": "safety_factor_yield", "min": 2.0}]
        return problem_from_dict(d)

    free = driver.run(problem(False), only=("device_size", "strength"))
    assert free.best.metrics["safety_factor_yield"] < 2.0  # the unconstrained optimum is too weak
    held = driver.run(problem(True), only=("device_size", "strength"))
    assert held.feasible
    assert held.best.metrics["safety_factor_yield"] >= 2.0 * (1 - 1e-3)
    assert held.best.x[0] > free.best.x[0]
