"""Batched throughput: many swinging rods in one call, rbody against MuJoCo; and the single-step cost.

Sizes 1, 64, 1024, 16384 and 10^6 rods (L = 1 m, theta0 spread over [0.1, 1.5] rad), dt = 1e-3,
each (mode, size) in its own subprocess so that its peak memory (ru_maxrss) is its own:

    rbody simulate    rbody.simulate(scene, dt, method="verlet", save_every): stepping and observables
    rbody kernel      the compiled Verlet loop simulate calls, alone (no model building, no observables)
    rbody lean        the fix proposed for large batches (lean_rods below): batch-innermost Verlet with the
                      pendulum's acceleration inlined, samples stored (S, 2, B) so theta and omega are
                      contiguous views, energy computed only when asked (energy_of_samples)
    mujoco rollout    one MjModel, the batch of initial states through mujoco.rollout with one MjData per
                      core (Euler: MuJoCo's default and cheapest step)
    mujoco loop       a plain Python loop of mj_step over one MjData, rod after rod (small sizes)

Every run saves SAMPLES + 1 samples (save_every = steps / SAMPLES), as the issue's 10^6 rods x 10^4
steps x 100 samples; the memory of a run depends on the samples, not on the steps, so the 10^6 batch is
stepped 2000 times (TARGET) with the same 101 samples: the same arrays, a fifth of the time (the saving
then costs 5 times more per step than at 10^4 steps). Reported: rod-steps per second, ns per
rod-step, peak resident memory and the memory after imports and warm-up.
"""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit, prange


DT = 1e-3
SAMPLES = 100
SIZES = {False: (1, 64, 1024, 16384, 10**6), True: (1, 64, 1024)}
# Rod-steps per measurement (steps = target / size, within [SAMPLES, 10^4]), per mode family: rbody's
# 10^6 rods take 2000 steps (a sample every 20 steps), MuJoCo's 10.
TARGET = {"rbody": {False: 2e9, True: 2e7}, "mujoco": {False: 4e6, True: 2e5}, "loop": {False: 2e5, True: 2e4}}
MODES = {False: ("rbody simulate", "rbody kernel", "rbody lean", "mujoco rollout", "mujoco loop"),
         True: ("rbody simulate", "rbody lean", "mujoco rollout")}
LOOP_MAX = 1024          # the plain mj_step loop only for sizes up to this
MEMORY_GOAL_GB = 2.0     # 10^6 rods, 101 samples
BATCH_GOAL_NS = 20.0     # per rod-step, at >= 1024 rods
SINGLE_GOAL_NS = 200.0   # one native step of one rod
CHUNK = 256              # rods per inner loop of lean_rods (fits L1 with q, v, a, k)
COLUMNS = ("mode", "size", "steps", "samples", "seconds", "rod_steps_per_second", "ns_per_rod_step", "peak_mb",
           "base_mb", "repeats", "failure")


def theta0(size: int) -> np.ndarray:
    return np.linspace(0.1, 1.5, size)


def steps_for(mode: str, size: int, quick: bool) -> int:
    family = "loop" if mode == "mujoco loop" else mode.split()[0]
    steps = int(TARGET[family][quick] / size)
    steps = min(max(steps, SAMPLES if family == "rbody" else 10), 10**4)
    return -(-steps // SAMPLES) * SAMPLES if family == "rbody" else steps


# ----- the fix, shown to work: lean batched rods ---------------------------------------------------------

@njit(cache=True, parallel=True)
def _lean_verlet(theta, omega, w0_squared, dt, nsteps, save_every, out):
    """Velocity Verlet on B rods, CHUNK rods per inner loop (the loop over rods innermost, so independent
    sines overlap), theta'' = -w0^2 sin(theta) inlined. out (S, 2, B): theta, omega at every save_every-th
    step. The same operations in the same order as rbody's verlet kernel: the same numbers, bit for bit.
    Returns the first sample index holding a non-finite state (-1 if none)."""
    size = theta.size
    chunks = (size + CHUNK - 1) // CHUNK
    bad = np.full(chunks, -1, dtype=np.int64)
    for c in prange(chunks):
        lo = c * CHUNK
        hi = min(size, lo + CHUNK)
        q = theta[lo:hi].copy()
        v = omega[lo:hi].copy()
        k = w0_squared[lo:hi]
        a = np.empty(hi - lo)
        for j in range(hi - lo):
            a[j] = -k[j] * np.sin(q[j])
        out[0, 0, lo:hi] = q
        out[0, 1, lo:hi] = v
        for i in range(1, nsteps + 1):
            for j in range(hi - lo):
                v[j] += 0.5 * dt * a[j]
                q[j] += dt * v[j]
                a[j] = -k[j] * np.sin(q[j])
                v[j] += 0.5 * dt * a[j]
            if i % save_every == 0:
                s = i // save_every
                out[s, 0, lo:hi] = q
                out[s, 1, lo:hi] = v
                if bad[c] < 0:
                    for j in range(hi - lo):
                        if not (np.isfinite(q[j]) and np.isfinite(v[j])):
                            bad[c] = s
                            break
    first = -1
    for c in range(chunks):
        if bad[c] >= 0 and (first < 0 or bad[c] < first):
            first = bad[c]
    return first


@njit(cache=True, parallel=True)
def energy_of_samples(out, moment, mgd, energy):
    """E = 1/2 I omega^2 - M g d cos(theta) [J] into energy (S, B), from out (S, 2, B): no temporaries."""
    samples, _two, size = out.shape
    for b in prange(size):
        for s in range(samples):
            energy[s, b] = 0.5 * moment[b] * out[s, 1, b] ** 2 - mgd[b] * np.cos(out[s, 0, b])


def lean_rods(scene, dt: float, nsteps: int, save_every: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A batch of swinging rods (rbody.scenes.swinging_rod with array theta0) by Verlet, the lean way.

    Returns t (S,) [s], theta (S, B) [rad] and omega (S, B) [rad/s], both contiguous views of one (S, 2, B)
    array; the energy is left to energy_of_samples, on request. Raises rbody.SimulationError on a
    non-finite state."""
    from rbody.errors import SimulationError

    model = scene.native()
    out = np.empty((nsteps // save_every + 1, 2, model.y0.shape[0]))
    first = _lean_verlet(np.ascontiguousarray(model.y0[:, 0]), np.ascontiguousarray(model.y0[:, 1]),
                         np.ascontiguousarray(model.params[:, 0]), dt, nsteps, save_every, out)
    if first >= 0:
        raise SimulationError(f"lean_rods: non-finite state by t={first * save_every * dt:.6g} s with dt={dt}")
    return np.arange(out.shape[0]) * (dt * save_every), out[:, 0], out[:, 1]


# ----- one measurement, in its own process --------------------------------------------------------------

def _rss_mb() -> float:
    """Peak resident memory of this process [MiB]: VmHWM of /proc/self/status, the high-water mark of this
    address space. (Linux keeps ru_maxrss across exec, so a worker started from a large parent would
    report the parent's size; VmHWM starts afresh at exec.) ru_maxrss where /proc is missing."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0  # kB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kilobytes on Linux


def _worker(mode: str, size: int, steps: int, repeats: int) -> dict:
    """Warm up (compile, load caches) on a small batch, then time `repeats` runs of the mode."""
    import rbody
    from rbody import scenes
    from rbody.engine import integrators
    from rbody.scenes.pendulum import pendulum_accel

    save_every = max(1, steps // SAMPLES)
    t_end = steps * DT

    def scene_of(n):
        return scenes.swinging_rod(1.0, theta0=theta0(n), t_end=t_end)

    if mode.startswith("rbody"):
        def prepare(n):
            scene = scene_of(n)
            if mode == "rbody simulate":
                return lambda: rbody.simulate(scene, dt=DT, method="verlet", save_every=save_every)
            if mode == "rbody lean":
                return lambda: lean_rods(scene, DT, steps, save_every)
            model = scene.native()
            out = np.empty((steps // save_every + 1,) + model.y0.shape)
            return lambda: integrators.run_composed_verlet(pendulum_accel, np.ones(1), model.y0, model.params, DT,
                                                           steps, save_every, out)
    else:
        prepare = _mujoco_runner(mode, steps, save_every, scene_of)
    prepare(4)()
    base = _rss_mb()
    run = prepare(size)
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        seconds.append(time.perf_counter() - start)
        del result
    return {"seconds": min(seconds), "peak_mb": _rss_mb(), "base_mb": base, "repeats": repeats}


def _mujoco_runner(mode: str, steps: int, save_every: int, scene_of):
    import mujoco
    from mujoco import rollout

    import rbody

    def prepare(n):
        model = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene_of(1).item(0), dt=DT, integrator="Euler"))
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        state = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, state, spec)
        states = np.tile(state, (n, 1))
        states[:, 1] = theta0(n)  # (time, qpos, qvel): the hinge angle
        if mode == "mujoco loop":
            def run():
                samples = np.empty((steps // save_every + 1, n, 2))
                for b in range(n):
                    mujoco.mj_setState(model, data, states[b], spec)
                    samples[0, b] = data.qpos[0], data.qvel[0]
                    for i in range(1, steps + 1):
                        mujoco.mj_step(model, data)
                        if i % save_every == 0:
                            samples[i // save_every, b] = data.qpos[0], data.qvel[0]
                return samples
            return run
        threads = (os.cpu_count() or 1) if n > 1 else 1
        datas = [mujoco.MjData(model) for _ in range(threads)]
        pool = rollout.Rollout(nthread=threads if n > 1 else 0)  # n = 1: on the calling thread
        chunk = save_every  # one rollout per sample: the output holds save_every steps of the batch

        def run():
            samples = np.empty((steps // chunk + 1, n, states.shape[1]))
            samples[0] = states
            buffer = np.empty((n, chunk, states.shape[1]))
            for s in range(1, steps // chunk + 1):
                pool.rollout(model, datas, samples[s - 1], nstep=chunk, state=buffer)
                samples[s] = buffer[:, -1]
            return samples
        return run
    return prepare


def measure(mode: str, size: int, quick: bool) -> dict:
    """One (mode, size) in a fresh subprocess; a row of batch.csv."""
    steps = steps_for(mode, size, quick)
    # one timed run when it is long (rough costs per rod-step: rbody 3e-8 s, MuJoCo 2e-6 s), else three
    repeats = 1 if size * steps * (3e-8 if mode.startswith("rbody") else 2e-6) > 3.0 else 3
    row = {"mode": mode, "size": size, "steps": steps, "samples": steps // max(1, steps // SAMPLES) + 1,
           "seconds": math.nan, "rod_steps_per_second": math.nan, "ns_per_rod_step": math.nan, "peak_mb": math.nan,
           "base_mb": math.nan, "repeats": repeats, "failure": ""}
    command = [sys.executable, "-m", "validation.bench.batch", "--worker", mode, str(size), str(steps), str(repeats)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=1800,
                          cwd=Path(__file__).resolve().parents[2])
    if done.returncode != 0:
        row["failure"] = f"worker failed: {(done.stderr.strip().splitlines() or ['?'])[-1][:200]}"
        return row
    result = json.loads(done.stdout.strip().splitlines()[-1])
    row.update(result)
    row["rod_steps_per_second"] = size * steps / result["seconds"]
    row["ns_per_rod_step"] = 1e9 * result["seconds"] / (size * steps)
    return row


# ----- single-step cost -------------------------------------------------------------------------------------

def _single_worker(steps: int) -> dict:
    """ns per step of one rod: the compiled Verlet loop alone and a whole simulate call; the fixed cost of
    a simulate call (one step) and of building the native model (scene.native()) [us]."""
    import rbody
    from rbody import scenes
    from rbody.engine import integrators
    from rbody.scenes.pendulum import pendulum_accel

    scene = scenes.swinging_rod(1.0, theta0=1.0, t_end=steps * DT)
    model = scene.native()
    out = np.empty((2,) + model.y0.shape)

    def best(run, repeats=5):
        run()
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            run()
            times.append(time.perf_counter() - start)
        return min(times)

    kernel = best(lambda: integrators.run_composed_verlet(pendulum_accel, np.ones(1), model.y0, model.params, DT,
                                                          steps, steps, out))
    whole = best(lambda: rbody.simulate(scene, dt=DT, method="verlet", save_every=steps // SAMPLES))
    fixed = best(lambda: rbody.simulate(scene, dt=DT, method="verlet", t_end=DT), 50)
    native = best(scene.native, 50)
    return {"steps": steps, "kernel_ns": 1e9 * kernel / steps, "simulate_ns": 1e9 * whole / steps,
            "call_us": 1e6 * fixed, "native_us": 1e6 * native}


def single_step(quick: bool) -> dict:
    """_single_worker in a subprocess with numba's default threads, and again with one thread (which
    shows what the launch of the parallel loop costs a single scene)."""
    steps = 10**5 if quick else 10**6
    out = {}
    for label, threads in (("default", None), ("one thread", "1")):
        env = dict(os.environ)
        if threads:
            env["NUMBA_NUM_THREADS"] = threads
        done = subprocess.run([sys.executable, "-m", "validation.bench.batch", "--single", str(steps)],
                              capture_output=True, text=True, timeout=600, env=env,
                              cwd=Path(__file__).resolve().parents[2])
        if done.returncode != 0:
            raise RuntimeError(f"single-step worker failed: {done.stderr.strip()[-300:]}")
        out[label] = json.loads(done.stdout.strip().splitlines()[-1])
    return out


# ----- the whole measurement -----------------------------------------------------------------------------

def run_batch(out: Path, *, quick: bool, header: list[str], log=sys.stderr) -> dict:
    """batch.csv, batch.png and the Markdown and goal lines of the summary."""
    from validation.bench.csvfile import write_csv

    rows = []
    for mode in MODES[quick]:
        for size in SIZES[quick]:
            if mode == "mujoco loop" and size > LOOP_MAX:
                continue
            start = time.perf_counter()
            rows.append(measure(mode, size, quick))
            r = rows[-1]
            print(f"  batch: {mode} x {size}: {r['ns_per_rod_step']:.3g} ns/rod-step, peak {r['peak_mb']:.0f} MB "
                  f"({time.perf_counter() - start:.1f} s) {r['failure']}", file=log, flush=True)
    write_csv(out / "batch.csv", rows, COLUMNS, header)
    single = single_step(quick)
    check = _lean_matches_simulate()
    figure = _plot(rows, out)
    return {"rows": rows, "single": single, "figure": figure, "markdown": _markdown(rows, single, check, figure),
            "goals": _goals(rows, single)}


def _lean_matches_simulate() -> float:
    """max |theta_lean - theta_simulate| over 1024 rods and 1000 steps [rad]: the fix changes no number."""
    import rbody
    from rbody import scenes

    scene = scenes.swinging_rod(1.0, theta0=theta0(1024), t_end=1.0)
    _t, theta, omega = lean_rods(scene, DT, 1000, 10)
    run = rbody.simulate(scene, dt=DT, method="verlet", save_every=10)
    return float(max(np.max(np.abs(theta - run["theta"])), np.max(np.abs(omega - run["omega"]))))


def _plot(rows: list[dict], out: Path) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from validation.report import save_figure  # here, not at import: the batch workers stay without matplotlib

    figure, (left, right) = plt.subplots(1, 2, figsize=(12, 4.6))
    for mode in MODES[False]:
        mine = [r for r in rows if r["mode"] == mode and not r["failure"]]
        if mine:
            sizes = [r["size"] for r in mine]
            left.loglog(sizes, [r["rod_steps_per_second"] for r in mine], "o-", label=mode)
            right.loglog(sizes, [r["peak_mb"] / 1024 for r in mine], "o-", label=mode)
    right.axhline(MEMORY_GOAL_GB * 1e9 / 2**30, color="red", lw=0.8, ls="--", label="2 GB")
    left.set(xlabel="rods in one call", ylabel="rod-steps per second", title="Batched swinging rods: throughput")
    right.set(xlabel="rods in one call", ylabel="peak resident memory [GiB]",
              title=f"Peak memory ({SAMPLES + 1} samples)")
    left.legend(fontsize=8)
    right.legend(fontsize=8)
    return save_figure(figure, out, "batch.png", dpi=100)


def _markdown(rows: list[dict], single: dict, check: float, figure: str) -> list[str]:
    lines = ["## Batched throughput: swinging rods", "",
             f"dt = {DT} s; each (mode, size) in its own process; {SAMPLES + 1} samples saved; the peak is the "
             "process's maximum resident memory, the base what it held after imports and warm-up. "
             "rbody runs on all cores (numba prange), MuJoCo's rollout with one MjData per core.", "",
             "| mode | rods | steps | ns per rod-step | rod-steps per second | peak [MB] | base [MB] |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["failure"]:
            lines.append(f"| {r['mode']} | {r['size']} | {r['steps']} | {r['failure']} | | | |")
        else:
            lines.append(f"| {r['mode']} | {r['size']} | {r['steps']} | {r['ns_per_rod_step']:.3g} | "
                         f"{r['rod_steps_per_second']:.3g} | {r['peak_mb']:.0f} | {r['base_mb']:.0f} |")
    d, one = single["default"], single["one thread"]
    lines += ["", f"Single rod, {d['steps']} steps (numba's default threads / one thread): the compiled Verlet loop "
              f"{d['kernel_ns']:.3g} / {one['kernel_ns']:.3g} ns per step; a whole simulate call "
              f"{d['simulate_ns']:.3g} / {one['simulate_ns']:.3g} ns per step; the fixed cost of a simulate call "
              f"(one step) {d['call_us']:.3g} / "
              f"{one['call_us']:.3g} us, of which building the native model (scene.native()) {d['native_us']:.3g} / "
              f"{one['native_us']:.3g} us. The difference between the two is the launch of the parallel loop "
              "for a batch of one. The lean loop gives the same states as simulate "
              f"(max difference {check:.3g} rad over 1024 rods x 1000 steps).", "", f"![batch]({figure})"]
    return lines


def _goals(rows: list[dict], single: dict) -> list[str]:
    d = single["default"]
    lines = [f"- one native step of the swinging rod under {SINGLE_GOAL_NS:g} ns: "
             f"{'met' if d['kernel_ns'] < SINGLE_GOAL_NS else 'missed'} ({d['kernel_ns']:.3g} ns, compiled "
             f"loop; {d['simulate_ns']:.3g} ns through simulate, {single['one thread']['kernel_ns']:.3g} ns on one "
             "thread)."]
    for mode in ("rbody simulate", "rbody kernel", "rbody lean"):
        big = [r for r in rows if r["mode"] == mode and r["size"] >= 1024 and not r["failure"]]
        if big:
            worst = max(big, key=lambda r: r["ns_per_rod_step"])
            met = worst["ns_per_rod_step"] < BATCH_GOAL_NS
            lines.append(f"- batched under {BATCH_GOAL_NS:g} ns per rod-step at >= 1024 rods ({mode}): "
                         f"{'met' if met else 'missed'} (worst {worst['ns_per_rod_step']:.3g} ns at "
                         f"{worst['size']} rods"
                         + ("" if met else f", {worst['ns_per_rod_step'] / BATCH_GOAL_NS:.2g}x over") + ").")
    for mode in ("rbody simulate", "rbody lean"):
        million = [r for r in rows if r["mode"] == mode and r["size"] >= 10**6]
        for r in million:
            gb = r["peak_mb"] * 2**20 / 1e9
            lines.append(f"- 10^6 rods with {r['samples']} samples under {MEMORY_GOAL_GB:g} GB peak ({mode}): "
                         + (r["failure"] or f"{'met' if gb < MEMORY_GOAL_GB else 'missed'} ({gb:.2f} GB)."))
    if not any(r["size"] >= 10**6 for r in rows):
        lines.append("- 10^6 rods under 2 GB: not measured in this (quick) run.")
    return lines


if __name__ == "__main__":
    if len(sys.argv) == 6 and sys.argv[1] == "--worker":
        print(json.dumps(_worker(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]))))
    elif len(sys.argv) == 3 and sys.argv[1] == "--single":
        print(json.dumps(_single_worker(int(sys.argv[2]))))
    else:
        sys.exit("usage: python -m validation.bench.batch --worker MODE SIZE STEPS REPEATS | --single STEPS")
