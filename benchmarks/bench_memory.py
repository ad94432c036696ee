"""Memory per body: peak resident memory of an rblog run of N free bodies, beside MuJoCo's.

Issue 18's target: for 10,000 and 100,000 free bodies, report the peak RSS per body; no more than
2 KB per body beyond the log buffers.

Each size runs in a fresh child process (so one size's allocations cannot hide another's):

1. import rblog and run a 2-body scene of the same kind, so the kernels are loaded (compiled the
   first time) and numba's and numpy's one-time allocations are made;
2. ``gc.collect()`` and read the resident set (VmRSS of /proc/self/status): the baseline;
3. parse the N-body scene (a ``random`` generator of boxes with random spins, no gravity, no
   ground: the free-body kernel only) and run it for ``--steps`` steps without recorders while a
   thread reads VmRSS every 2 ms (the kernel releases the GIL): the peak;
4. (peak - baseline) / N is the memory per body. The run's sample buffers (the "log buffers":
   every block of samples handed to the recorders, 176 B per body-sample, up to
   runner.samples_per_block(N, stride) + 1 samples per block, at most two blocks queued and one
   being filled) are computed from the same constants and subtracted, giving the memory per body
   beyond the log buffers. By default a sample is taken at the start and the end only, so the
   buffers are a few hundred bytes per body and the figure is the simulation's own.

MuJoCo (if installed): the same N boxes as free bodies, the same steps: its resident memory
after building the model and stepping, minus a 2-body model's (the pages it touched), and in
brackets the bytes it reserved (``model.nbuffer + data.nbuffer + data.narena``; the arena is set
to 40 KB per body plus 3 n^2 bytes, since MuJoCo's default is too small at 10,000 bodies and its
broadphase asks for 2 n^2 bytes), per body, for scale. MuJoCo is built only up to 10,000 bodies.

    python benchmarks/bench_memory.py                 # 10,000 and 100,000 bodies
    python benchmarks/bench_memory.py --bodies 1000 --steps 50
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

#: issue 18's bound on memory per body beyond the log buffers (bytes)
TARGET_BYTES_PER_BODY = 2048

#: float64 channels of one body-sample in the run's sample buffers: position 3, momentum 3,
#: quaternion 4, rotation 9, angular momentum 3 (runner.run's new_buffers)
SAMPLE_BYTES_PER_BODY = (3 + 3 + 4 + 9 + 3) * 8

SCENE = """
[sim]
dt = 1e-3
duration = 1.0
gravity = [0.0, 0.0, 0.0]
seed = 3
log_every = {stride}
[[generator]]
layout = "random"
count = {n}
region_min = [-100.0, -100.0, -100.0]
region_max = [100.0, 100.0, 100.0]
spin = [0.0, 10.0]
[generator.body]
shape = "box"
half_extents = [0.1, 0.05, 0.02]
mass = 1.0
"""

CHILD = r"""
import gc, json, sys, threading, time
n, steps, stride = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
scene_text = sys.argv[4]

def rss():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmRSS")

import rblog
from rblog.engine.runner import run, samples_per_block
from rblog.engine.scene import parse_scene

run(parse_scene(scene_text.format(n=2, stride=stride), "warm.toml"), duration=steps * 1e-3)
gc.collect()
base = rss()
peak = [base]
done = threading.Event()

def sample():
    while not done.is_set():
        peak[0] = max(peak[0], rss())
        time.sleep(0.002)

th = threading.Thread(target=sample, daemon=True)
th.start()
t0 = time.perf_counter()
scene = parse_scene(scene_text.format(n=n, stride=stride), "bodies.toml")
t_parse = time.perf_counter() - t0
peak[0] = max(peak[0], rss())
t0 = time.perf_counter()
run(scene, duration=steps * 1e-3)
t_run = time.perf_counter() - t0
peak[0] = max(peak[0], rss())
done.set()
th.join()
print(json.dumps({"n": n, "base": base, "peak": peak[0], "t_parse": t_parse, "t_run": t_run,
                  "samples_per_block": samples_per_block(n, stride)}))
"""

MUJOCO_CHILD = r"""
import gc, json, sys
import mujoco
n, steps = int(sys.argv[1]), int(sys.argv[2])

def rss():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024

def model(k):
    bodies = "".join(
        f'<body pos="{(i % 100) * 0.5} {(i // 100 % 100) * 0.5} {i // 10000 * 0.5}"><freejoint/>'
        f'<geom type="box" size="0.1 0.05 0.02" mass="1"/></body>' for i in range(k))
    # the arena grows with the model (its broadphase alone asks for 2 n^2 bytes)
    memory_k = (40_000 * k + 3 * k * k) // 1024 + 1024
    return (f'<mujoco><size memory="{memory_k}K"/><option gravity="0 0 0"/>'
            f'<worldbody>{bodies}</worldbody></mujoco>')

m = mujoco.MjModel.from_xml_string(model(2))
d = mujoco.MjData(m)
mujoco.mj_step(m, d)
del m, d
gc.collect()
base = rss()
m = mujoco.MjModel.from_xml_string(model(n))
d = mujoco.MjData(m)
for _ in range(steps):
    mujoco.mj_step(m, d)
print(json.dumps({"rss": rss() - base, "buffers": int(m.nbuffer + d.nbuffer + d.narena)}))
"""


def rblog_figures(n: int, steps: int, stride: int) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(n), str(steps), str(stride), SCENE],
                         capture_output=True, text=True, check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    per_body = (r["peak"] - r["base"]) / n
    # sample buffers alive at once: the block being filled + QUEUE_BLOCKS (2) queued, each of
    # samples_per_block + 1 samples (runner.new_buffers)
    per_call = min(r["samples_per_block"], steps // stride)
    log_per_body = 3 * (per_call + 1) * SAMPLE_BYTES_PER_BODY
    r.update(per_body=per_body, log_per_body=log_per_body, beyond=per_body - log_per_body)
    return r


def mujoco_figures(n: int, steps: int) -> dict | None:
    try:
        out = subprocess.run([sys.executable, "-c", MUJOCO_CHILD, str(n), str(steps)],
                             capture_output=True, text=True, check=True, timeout=600)
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired) as e:
        print(f"  MuJoCo at {n} bodies: not measured ({type(e).__name__})", file=sys.stderr)
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bodies", default="10000,100000", help="comma-separated body counts")
    ap.add_argument("--steps", type=int, default=200, help="steps run after parsing")
    ap.add_argument("--log-every", type=int, default=0,
                    help="sample stride (steps); default: --steps (a sample at the start and the "
                         "end, so the log buffers are small and the rest is the simulation's)")
    ap.add_argument("--no-mujoco", action="store_true")
    ap.add_argument("--mujoco-max", type=int, default=10_000, help="largest N built in MuJoCo")
    a = ap.parse_args(argv)
    a.log_every = a.log_every or a.steps
    try:
        import mujoco  # noqa: F401
        have_mujoco = not a.no_mujoco
    except ImportError:
        have_mujoco = False
    print(f"peak resident memory per free body; {a.steps} steps, a sample every {a.log_every}; "
          f"target <= {TARGET_BYTES_PER_BODY} B per body beyond the log buffers")
    print("| bodies | rblog peak - base (B/body) | log buffers (B/body) | beyond them (B/body) "
          "| target | MuJoCo RSS after set-up and steps (mjModel+mjData+arena) (B/body) |")
    print("|---|---|---|---|---|---|")
    worst = 0.0
    for n in (int(x) for x in a.bodies.split(",")):
        r = rblog_figures(n, a.steps, a.log_every)
        mj = mujoco_figures(n, a.steps) if have_mujoco and n <= a.mujoco_max else None
        mj_s = f"{mj['rss'] / n:,.0f} ({mj['buffers'] / n:,.0f})" if mj else "-"
        met = "met" if r["beyond"] <= TARGET_BYTES_PER_BODY else "NOT met"
        worst = max(worst, r["beyond"])
        print(f"| {n:,} | {r['per_body']:,.0f} | {r['log_per_body']:,.0f} | {r['beyond']:,.0f} "
              f"| <= {TARGET_BYTES_PER_BODY}: {met} | {mj_s} |", flush=True)
    return 0 if worst <= TARGET_BYTES_PER_BODY else 1


if __name__ == "__main__":
    sys.exit(main())
