"""An independent check: a drop-stand simulator written without impactometer's model code, its records written
as a lab would (CSV in kN and g, HDF5, TDMS), identified by impactometer from the files.

Axis down, SI. Mass M1 (free flight) hits the rod of a pneumatic cylinder (piston and rod M2) held at its top stop
by the gas force. Gas: adiabatic, p = p0·(L/(L − x2))^1.4, force (p − patm)·A upward. Coulomb seal friction
Ff·tanh(v2/1 mm/s). Top stop: a preloaded stiff one-sided spring (1e9 N/m, damped), so that x2 = 0, v2 = 0 is the
equilibrium before contact. Contact: Kelvin-Voigt (k, damping ratio ζ) or Hunt-Crossley (k, α) on the overlap
d = x1 − x2, integrated by scipy's LSODA (rtol 1e-9, steps of at most 2 µs).

Records: 50 kHz point samples of the contact force [N] and the kinematic piston acceleration [m/s²] (no anti-alias
filter), 20 ms of pre-trigger and 60 ms after first contact, the sample grid at a random phase to the contact,
white noise of ``--noise`` × each channel's RMS after contact. Cases: M1 8-60 kg, V0 0.8-3.5 m/s, M2 3-6 kg, A
20-35 cm², L 0.2-0.3 m, p0 20-400 kPa gauge, Ff 50-150 N; KV: k 0.5-2e6 N/m, ζ 0.05-0.2; HC: k 1-5e7 N/m^1.5,
α 0.1-0.4 s/m. Files rotate CSV (``time [ms]``, ``Force [kN]``, ``Acceleration (g)``) / HDF5 / TDMS.

    python scripts/independent_stand.py OUT                # 40 records per law at 5 % noise, then the table
    python scripts/independent_stand.py OUT --noise 0      # the same cases without noise: the method's own bias

The table: per law, mean / max |relative error| of the final answer's mass and velocity [%], ±2σ coverage, the
early answer's mean mass error and coverage, and refusals (each named).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from multiprocessing import Pool
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # benchmarks/recorded.py

import numpy as np
from scipy.integrate import solve_ivp

from recorded import recorded

G = 9.80665
PATM = 101325.0
FS = 50e3
PRE = 0.020
POST = 0.060
K_STOP = 1e9


def draw_case(law: str, idx: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    M1 = rng.uniform(8, 60)
    V0 = rng.uniform(0.8, 3.5)
    M2 = rng.uniform(3, 6)
    A = rng.uniform(0.0020, 0.0035)
    L = rng.uniform(0.2, 0.3)
    Ff = rng.uniform(50, 150)
    while True:  # the gas must hold the piston against its top stop
        gauge = rng.uniform(20e3, 400e3)
        if gauge * A > 1.2 * M2 * G:
            break
    p: dict = dict(law=law, idx=idx, seed=seed, M1=M1, V0=V0, M2=M2, A=A, L=L, Ff=Ff, gauge=gauge,
                   phase=rng.uniform(0, 1.0 / FS))
    if law == "KV":
        k, zeta = rng.uniform(0.5e6, 2e6), rng.uniform(0.05, 0.2)
        mu = M1 * M2 / (M1 + M2)
        p.update(k=k, zeta=zeta, c=2 * zeta * math.sqrt(k * mu))
    else:
        p["k"] = rng.uniform(1e7, 5e7)
        p["alpha"] = rng.uniform(0.1, 0.4)
    return p


def make_rhs(p):
    M1, M2, A, L, Ff = p["M1"], p["M2"], p["A"], p["L"], p["Ff"]
    p0 = p["gauge"] + PATM
    pre = p["gauge"] * A - M2 * G        # stop preload at x2 = 0
    s_stop = pre / K_STOP                # stop surface position (equilibrium penetration at x2 = 0)
    c_stop = 2 * 0.5 * math.sqrt(K_STOP * M2)
    kv = p["law"] == "KV"
    k = p["k"]
    c = p.get("c", 0.0)
    alpha = p.get("alpha", 0.0)

    def contact(x1, v1, x2, v2):
        d = x1 - x2
        if d <= 0.0:
            return 0.0
        dd = v1 - v2
        f = k * d + c * dd if kv else k * d ** 1.5 * (1.0 + 1.5 * alpha * dd)
        return f if f > 0.0 else 0.0

    def piston_forces(x2, v2, F):
        gas = (p0 * (L / (L - x2)) ** 1.4 - PATM) * A
        fric = Ff * math.tanh(v2 / 1e-3)
        stop = 0.0
        if x2 < s_stop:
            stop = K_STOP * (s_stop - x2) - c_stop * v2
            if stop < 0.0:
                stop = 0.0
        return M2 * G + F - gas - fric + stop

    def rhs(t, y):
        x1, v1, x2, v2 = y
        F = contact(x1, v1, x2, v2)
        return [v1, G - F / M1, v2, piston_forces(x2, v2, F) / M2]

    return rhs, contact, piston_forces


def simulate(p):
    rhs, contact, piston_forces = make_rhs(p)
    t0 = -1e-3
    V0 = p["V0"]
    y0 = [V0 * t0 + 0.5 * G * t0 ** 2, V0 + G * t0, 0.0, 0.0]   # free flight so that x1(0) = 0, v1(0) = V0
    sol = solve_ivp(rhs, (t0, POST + 1e-4), y0, method="LSODA", rtol=1e-9, atol=[1e-12, 1e-9, 1e-12, 1e-9],
                    max_step=2e-6, dense_output=True)
    if not sol.success:
        raise RuntimeError(sol.message)
    n_pre = int(round(PRE * FS))
    n_post = int(round(POST * FS))
    # sample grid: t_k = start + k/fs, with the contact at a random phase inside a sample period
    start = -n_pre / FS + p["phase"]
    t = start + np.arange(n_pre + n_post) / FS
    F = np.zeros_like(t)
    a = np.zeros_like(t)
    after = t >= t0
    Y = sol.sol(t[after])
    Fa = np.empty(Y.shape[1])
    aa = np.empty(Y.shape[1])
    for i in range(Y.shape[1]):
        x1, v1, x2, v2 = Y[:, i]
        f = contact(x1, v1, x2, v2)
        Fa[i] = f
        aa[i] = piston_forces(x2, v2, f) / p["M2"]
    F[after] = Fa
    a[after] = aa
    # before contact: exactly zero (numerical residue of the stop equilibrium removed)
    F[t < 0] = 0.0
    a[t < 0] = 0.0
    x2max = float(np.max(sol.y[2]))
    return t, F, a, x2max, sol


def add_noise(p, t, F, a, level=0.05):
    rng = np.random.default_rng(p["seed"] + 1_000_003)
    post = t >= 0
    sF = level * math.sqrt(np.mean(F[post] ** 2))
    sa = level * math.sqrt(np.mean(a[post] ** 2))
    return F + rng.normal(0, sF, F.size), a + rng.normal(0, sa, a.size), sF, sa


def write_csv(path, t, F, a):
    data = np.column_stack([t * 1e3, F / 1e3, a / G])
    np.savetxt(path, data, delimiter=",", fmt=["%.6f", "%.9g", "%.9g"],
               header="time [ms],Force [kN],Acceleration (g)", comments="")


def write_h5(path, t, F, a):
    import h5py
    with h5py.File(path, "w") as h:
        h.attrs["sample_rate"] = FS
        h.attrs["start_time"] = float(t[0])
        d = h.create_dataset("Force", data=F)
        d.attrs["unit"] = "N"
        d = h.create_dataset("Acceleration", data=a)
        d.attrs["unit"] = "m/s^2"


def write_tdms(path, t, F, a):
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter
    root = RootObject(properties={"name": os.path.basename(path)})
    group = GroupObject("Measurement", properties={})
    objs = [root, group]
    for name, values, unit in [("Force", F, "N"), ("Acceleration", a, "m/s^2")]:
        objs.append(ChannelObject("Measurement", name, np.asarray(values, dtype=np.float64), properties={
            "wf_increment": 1.0 / FS, "wf_start_offset": float(t[0]), "wf_samples": int(values.size),
            "wf_start_time": np.datetime64("2024-05-01T12:00:00"), "unit_string": unit,
            "NI_ChannelName": name, "NI_UnitDescription": unit}))
    with TdmsWriter(path) as w:
        w.write_segment(objs)


STYLES = [("csv", write_csv), ("h5", write_h5), ("tdms", write_tdms)]


def job(args):
    outdir, law, idx, seed, level = args
    p = draw_case(law, idx, seed)
    tic = time.time()
    t, F, a, x2max, _ = simulate(p)
    Fn, an, sF, sa = add_noise(p, t, F, a, level)
    ext, writer = STYLES[idx % 3]
    path = os.path.join(outdir, f"{law}_{idx:02d}.{ext}")
    writer(path, t, Fn, an)
    p.update(file=path, x2max=x2max, noise_F=sF, noise_a=sa, peak_F=float(F.max()), sim_s=time.time() - tic,
             n_pulses=int(np.sum(np.diff((F > 0).astype(int)) == 1)))
    return p


def evaluate(cases: list[dict]) -> None:
    """Identify every record from its file and print the accuracy table."""
    from impactometer.errors import IdentificationError
    from impactometer.identify.peak_to_peak import identify
    from impactometer.io import read_recording

    for law in ("KV", "HC"):
        rows, refused = [], []
        for p in (c for c in cases if c["law"] == law):
            try:
                r = identify(read_recording(p["file"]))
            except IdentificationError as exc:
                refused.append(f"{os.path.basename(p['file'])}: {exc}")
                continue
            e = r.early
            rows.append([r.mass / p["M1"] - 1, r.velocity / p["V0"] - 1, (r.mass - p["M1"]) / r.mass_std,
                         (r.velocity - p["V0"]) / r.velocity_std,
                         np.nan if e is None else e.mass / p["M1"] - 1,
                         np.nan if e is None else (e.mass - p["M1"]) / e.mass_std,
                         np.nan if e is None else (e.velocity - p["V0"]) / e.velocity_std])
        a = np.array(rows)
        early = a[np.isfinite(a[:, 4])]
        print(f"{law}: {len(a)} answered, {len(refused)} refused; final: mass {100 * np.mean(abs(a[:, 0])):.2f} / "
              f"{100 * np.max(abs(a[:, 0])):.2f} %, velocity {100 * np.mean(abs(a[:, 1])):.3f} / "
              f"{100 * np.max(abs(a[:, 1])):.2f} %, ±2σ coverage {np.mean(abs(a[:, 2]) <= 2):.0%} / "
              f"{np.mean(abs(a[:, 3]) <= 2):.0%}; early ({len(early)}): mass {100 * np.mean(abs(early[:, 4])):.2f} "
              f"%, coverage {np.mean(abs(early[:, 5]) <= 2):.0%} / {np.mean(abs(early[:, 6]) <= 2):.0%}")
        for line in refused:
            print(f"  refused {line}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", help="folder for the records and manifest.json (created)")
    ap.add_argument("--per-law", type=int, default=40, help="records per contact law")
    ap.add_argument("--noise", type=float, default=0.05, help="noise, fraction of each channel's RMS")
    ap.add_argument("--jobs", type=int, default=2, help="simulation processes")
    ap.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = ap.parse_args()
    with recorded("independent_stand", "Identification of records from an independent drop-stand simulator",
                  args.record):
        measure(args)


def measure(args) -> None:
    os.makedirs(args.out, exist_ok=True)
    jobs = [(args.out, law, i, 7000 + 100 * li + i, args.noise) for li, law in enumerate(["KV", "HC"])
            for i in range(args.per_law)]
    with Pool(max(args.jobs, 1)) as pool:
        cases = pool.map(job, jobs, chunksize=1)
    with open(os.path.join(args.out, "manifest.json"), "w") as f:
        json.dump(cases, f, indent=1)
    print(f"{len(cases)} records in {args.out}, simulated in {np.mean([c['sim_s'] for c in cases]):.1f} s each")
    evaluate(cases)


if __name__ == "__main__":
    main()
