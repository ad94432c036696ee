"""rblog bench / rblog stress: the exact references, the --quick smoke runs (well-formed JSON, CSV
and PNG) and the qualitative facts the full study rests on (orders of convergence 1, 2, 4; the
notes' scheme gaining energy; splitting keeping |L| and R orthonormal; blow-ups caught)."""

from __future__ import annotations

import csv
import json
import math

import click
import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("scipy")

from rblog.study import bench, stress  # noqa: E402
from rblog.study.reference import (  # noqa: E402
    PROBLEMS,
    Samples,
    TorqueFree,
    bouncing_ball,
    bouncing_ball_apexes,
    find_apexes,
    get_problem,
    quat_to_matrix,
    two_sphere_velocities,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
STATUSES = {"ok", "diverged", "unavailable", "error"}


# ---- exact references ------------------------------------------------------------------------

def _euler_numeric(inertia, w0, t):
    from scipy.integrate import solve_ivp

    i = np.asarray(inertia, float)

    def rhs(_, w):
        return [(i[1] - i[2]) / i[0] * w[1] * w[2], (i[2] - i[0]) / i[1] * w[2] * w[0],
                (i[0] - i[1]) / i[2] * w[0] * w[1]]

    return solve_ivp(rhs, (0, t[-1]), w0, method="DOP853", rtol=1e-13, atol=1e-14, t_eval=t).y.T


@pytest.mark.parametrize("inertia, w0, case", [
    ((1.0, 2.0, 3.0), (0.05, 2.0, 0.05), "L2>2EI2"),     # the intermediate-axis box
    ((1.0, 1.5, 2.2), (1.4, 0.5, 0.7), "L2<2EI2"),       # the generic case
    ((3.0, 1.0, 2.0), (0.3, -1.0, 0.2), None),           # unsorted moments (even permutation)
    ((2.0, 1.0, 3.0), (-0.4, 0.2, 1.5), None),           # odd permutation
    ((1.0, 1.0, 2.0), (0.3, 0.4, 1.0), "symmetric"),
])
def test_torque_free_elliptic_solution_matches_euler_equations(inertia, w0, case):
    t = np.linspace(0.0, 20.0, 801)
    tf = TorqueFree(inertia, w0)
    if case is not None:
        assert tf.case == case
    np.testing.assert_allclose(tf.omega_body(t), _euler_numeric(inertia, w0, t), atol=1e-10)


def test_intermediate_axis_flips_at_the_known_times():
    tf = TorqueFree((1.0, 2.0, 3.0), (0.05, 2.0, 0.05))
    t = np.linspace(0.0, 20.0, 200_001)
    wy = tf.omega_body(t)[:, 1]
    k = np.nonzero(np.sign(wy[1:]) != np.sign(wy[:-1]))[0]
    np.testing.assert_allclose(t[k], [4.663209, 12.849353], atol=2e-4)
    assert tf.period == pytest.approx(2 * (12.849353 - 4.663209), abs=1e-5)


def test_orientation_reference_keeps_world_angular_momentum():
    q0 = np.array([0.8, 0.3, -0.4, 0.34])
    tf = TorqueFree((1.0, 1.5, 2.2), (1.4, 0.5, 0.7), q0)
    t = np.linspace(0.0, 10.0, 501)
    l_world = np.einsum("tij,tj->ti", quat_to_matrix(tf.quat_wxyz(t)),
                        tf.inertia * tf.omega_body(t))
    np.testing.assert_allclose(l_world, np.tile(tf.angular_momentum_world, (len(t), 1)), atol=1e-10)


def test_bounce_and_impact_formulas():
    heights, impacts, apex_t = bouncing_ball_apexes(1.0, 0.8, 3, g=9.81)
    np.testing.assert_allclose(heights, [0.64, 0.4096, 0.262144])
    assert impacts[0] == pytest.approx(math.sqrt(2 / 9.81))
    # sampled exact bounce: the apex finder recovers the heights to round-off
    t = np.arange(0.0, impacts[-1], 1e-3)
    z = np.empty_like(t)
    v0 = math.sqrt(2 * 9.81)
    for k, tk in enumerate(t):
        if tk < impacts[0]:
            z[k] = 1.0 - 0.5 * 9.81 * tk**2
        else:
            j = np.searchsorted(impacts, tk) - 1
            s, v = tk - impacts[j], 0.8 ** (j + 1) * v0
            z[k] = v * s - 0.5 * 9.81 * s * s
    np.testing.assert_allclose(find_apexes(t, z, 3, 0.01), heights, atol=1e-12)
    u1, u2 = two_sphere_velocities(1.0, 3.0, 2.0, -1.0, 0.7)
    assert 1.0 * u1 + 3.0 * u2 == pytest.approx(2.0 - 3.0)
    assert u2 - u1 == pytest.approx(0.7 * 3.0)


def test_bounce_evaluator_on_the_exact_motion():
    p = bouncing_ball()
    heights, impacts, _ = bouncing_ball_apexes(1.0, 0.8, 3)
    t = np.arange(0.0, p.duration, 1e-3)
    z = np.array([_exact_bounce_z(tk, impacts) for tk in t]) + 0.1
    n = len(t)
    s = Samples(t, np.stack([np.zeros(n), np.zeros(n), z], -1)[:, None], np.tile([1.0, 0, 0, 0], (n, 1, 1)),
                np.zeros((n, 1, 3)), np.zeros((n, 1, 3)))
    assert p.evaluate(s)["apex_m"] < 1e-12


def _exact_bounce_z(tk, impacts, e=0.8, g=9.81):
    if tk < impacts[0]:
        return 1.0 - 0.5 * g * tk**2
    j = min(np.searchsorted(impacts, tk) - 1, len(impacts) - 1)
    s, v = tk - impacts[j], e ** (j + 1) * math.sqrt(2 * g)
    return max(v * s - 0.5 * g * s * s, 0.0)


# ---- rblog bench --quick ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def bench_quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    report = bench.run_bench(quick=True, peers=())
    files = bench.write_outputs(report, out)
    return report, files


def test_bench_json_is_well_formed(bench_quick):
    report, files = bench_quick
    d = json.loads(open(files["json"], encoding="utf-8").read())
    assert d["schema"] == bench.SCHEMA and d["kind"] == "bench" and d["quick"] is True
    for k in ("machine", "settings", "problems", "runs", "orders", "peer_ratios", "files", "notes"):
        assert k in d
    assert [p["name"] for p in d["problems"]] == list(PROBLEMS)
    assert d["machine"]["cores"] >= 1
    assert len(d["runs"]) == len(PROBLEMS) * len(bench.INTEGRATORS) * len(bench.DTS_QUICK)
    for r in d["runs"]:
        assert set(r) == set(bench.CSV_COLUMNS)
        assert r["status"] in STATUSES
        if r["status"] == "ok":
            assert r["error"] is not None and r["error"] >= 0 and r["wall_per_sim_s"] > 0
        else:
            assert r["message"]
    for p in d["problems"]:
        if p["contacts"] and not p["available"]:
            assert p["reason"]  # "unavailable: <reason>", never a crash
        if not p["contacts"]:
            assert p["available"]
            assert any(r["pareto"] for r in d["runs"] if r["problem"] == p["name"])


def test_bench_csv_columns(bench_quick):
    report, files = bench_quick
    with open(files["csv"], newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0].keys()) == bench.CSV_COLUMNS
    assert len(rows) == len(report.rows)
    assert {r["problem"] for r in rows} == set(PROBLEMS)


def test_bench_plot_is_a_png(bench_quick):
    pytest.importorskip("matplotlib")
    _, files = bench_quick
    with open(files["png"], "rb") as f:
        assert f.read(8) == PNG_MAGIC


def test_bench_orders_of_convergence_on_the_generic_body(bench_quick):
    report, _ = bench_quick
    orders = report.orders["torque-free-generic"]
    assert orders["rblog/seed"]["omega_rel"] == pytest.approx(1.0, abs=0.25)
    assert orders["rblog/seed-quat"]["omega_rel"] == pytest.approx(1.0, abs=0.25)
    assert orders["rblog/splitting"]["angle_rad"] == pytest.approx(2.0, abs=0.25)
    assert orders["rblog/rk4"]["angle_rad"] == pytest.approx(4.0, abs=0.4)


def test_bench_invariants(bench_quick):
    report, _ = bench_quick
    for r in report.rows:
        if r["problem"] not in ("torque-free-intermediate", "torque-free-generic"):
            continue
        assert r["status"] == "ok"
        if r["integrator"] == "seed":  # the notes' scheme gains energy on torque-free motion
            assert r["energy_growth_rel"] > 1e-3
        if r["integrator"] == "splitting":  # keeps |L| and R^T R = I to round-off
            assert r["angular_momentum_drift_rel"] < 1e-13
            assert r["ortho_error_max"] < 1e-13
            assert r["energy_drift_rel"] < 1e-3


def test_bench_table_names_every_problem(bench_quick):
    report, _ = bench_quick
    text = bench.format_table(report)
    for name in PROBLEMS:
        assert name in text
    assert "orders of convergence" in text


def test_bench_contact_problems_are_scored():
    # a box set down on the ground must not move (exact answer: zero displacement)
    p = get_problem("resting-box")
    row = bench.run_rblog(p, "rk4", 1e-2, timing=False)
    assert row["status"] == "ok", row.get("message")
    assert row["position_m"] <= 1e-6


def test_peer_mujoco_side_by_side():
    pytest.importorskip("mujoco")
    from rblog.study.peers import MujocoPeer

    peer = MujocoPeer()
    p = get_problem("torque-free-generic")
    rk4 = bench.run_peer(peer, p, "RK4", 1e-2, timing=False)
    euler = bench.run_peer(peer, p, "Euler", 1e-2, timing=False)
    assert rk4["status"] == "ok" and rk4["angle_rad"] < 1e-6
    assert euler["status"] == "ok" and euler["energy_drift_rel"] > 1e-3


# ---- rblog stress --quick --------------------------------------------------------------------

@pytest.fixture(scope="module")
def stress_quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("stress")
    report = stress.run_stress(quick=True)
    files = stress.write_outputs(report, out)
    return report, files


def test_stress_json_is_well_formed(stress_quick):
    report, files = stress_quick
    d = json.loads(open(files["json"], encoding="utf-8").read())
    assert d["schema"] == stress.SCHEMA and d["kind"] == "stress"
    assert [c["name"] for c in d["cases"]] == list(stress.CASE_NAMES)
    for r in d["runs"]:
        assert set(r) == set(stress.ROW_FIELDS)
        assert r["status"] in {"stable", "unstable", "diverged", "unavailable", "error"}
        if r["status"] in ("unstable", "diverged", "unavailable", "error"):
            assert r["message"]
    for c in d["cases"]:
        if not c["available"]:
            assert c["contacts"] and c["reason"]
    assert set(d["largest_stable_dt"]) == {"dt-sweep", "dt-sweep-contact"}


def test_stress_plot_is_a_png(stress_quick):
    pytest.importorskip("matplotlib")
    _, files = stress_quick
    with open(files["png"], "rb") as f:
        assert f.read(8) == PNG_MAGIC


def test_stress_blow_up_is_caught_and_located(stress_quick):
    report, _ = stress_quick
    spin = {(r["variant"], r["integrator"]): r for r in report.rows if r["case"] == "spin"}
    # without orthonormalization the notes' scheme stretches the body until it overflows
    r = spin[("|w| = 1000 rad/s", "seed/none")]
    assert r["status"] == "diverged" and r["stable"] is False
    assert r["first_bad_step"] > 0 and "non-finite" in r["first_bad_what"]
    # ... and the suite went on: the later integrators of that variant ran
    assert spin[("|w| = 1000 rad/s", "rk4")]["status"] in ("stable", "unstable")
    for spec in ("splitting", "rk4"):
        assert spin[("|w| = 10 rad/s", spec)]["stable"]


def test_stress_qualitative_facts(stress_quick):
    report, _ = stress_quick
    rows = {(r["case"], r["variant"], r["integrator"]): r for r in report.rows}
    # the notes' scheme gains energy; splitting and rk4 hold the thin rod
    assert rows[("dt-sweep", "dt = 0.01 s", "seed")]["energy_growth_rel"] > 0
    for spec in ("splitting", "rk4"):
        assert rows[("inertia", "1:1e+04", spec)]["stable"]
    assert rows[("inertia", "1:1e+04", "seed")]["stable"] is False
    sweep = report.largest_stable_dt["dt-sweep"]
    assert sweep["splitting"] >= sweep["seed"]
    assert sweep["rk4"] >= sweep["seed"]


def test_stress_table(stress_quick):
    report, _ = stress_quick
    text = stress.format_table(report)
    for name in stress.CASE_NAMES:
        assert name in text
    assert "largest stable dt" in text


# ---- the commands ------------------------------------------------------------------------------

@pytest.fixture
def cli():
    from rblog_cli.bench_cmds import bench as bench_cmd
    from rblog_cli.bench_cmds import stress as stress_cmd

    group = click.Group("rblog")
    group.add_command(bench_cmd)
    group.add_command(stress_cmd)
    return group


def test_cli_bench_json(cli, tmp_path):
    res = CliRunner().invoke(cli, ["bench", "--quick", "--no-peers", "--problem", "free-fall",
                                   "--integrator", "splitting", "--out", str(tmp_path), "--json"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)
    assert {r["integrator"] for r in d["runs"]} == {"splitting"}
    assert (tmp_path / "bench.csv").exists() and (tmp_path / "bench.json").exists()


def test_cli_bench_table_and_bad_input(cli, tmp_path):
    res = CliRunner().invoke(cli, ["bench", "--quick", "--no-peers", "--problem", "torque-free-generic",
                                   "--integrator", "rk4", "--dt", "0.01", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert "torque-free-generic" in res.output and "wrote" in res.output
    res = CliRunner().invoke(cli, ["bench", "--problem", "nope", "--out", str(tmp_path)])
    assert res.exit_code == 2 and "unknown problem" in res.output
    res = CliRunner().invoke(cli, ["bench", "--integrator", "rk4/polar", "--out", str(tmp_path)])
    assert res.exit_code == 2


def test_cli_stress_json(cli, tmp_path):
    res = CliRunner().invoke(cli, ["stress", "--quick", "--case", "spin", "--case", "impact",
                                   "--integrator", "seed/none", "--out", str(tmp_path), "--json"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)
    assert {r["case"] for r in d["runs"]} == {"spin", "impact"}
    assert any(r["status"] == "diverged" for r in d["runs"])
