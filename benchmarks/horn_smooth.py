"""Is the horn stage's cost rough in its parameters, and where from? Fine 1-D scans (issue 15, hornans20).

Run: ``.venv/bin/python benchmarks/horn_smooth.py --runs DIR [DIR ...] [--ends 0] [--params play wc al zeta]
[--span 0.1] [--points 121] [--modes native kelvin:1 ramp:1 kelvin:2 ramp:2]`` on the live runs ``benchmarks/online.py
--keep DIR`` kept (step 5 on the slow phase plus the fast part's first ``--ends`` seconds; 0: all).

Per record: step 5's massless search and horn stage (``fit_loop(load=False)``, ``with_horn``); where the horn is
kept, its answer's cost on every kept sample is scanned along one parameter at a time (the others held at the
answer), the parameter times ``exp(x)`` for ``x`` on ``--points`` points over ``[-span, span]``:

- ``native``: the model as the fit simulates it (:func:`~servoid.ident.models.servo_loop.contact_substeps`: the
  contact's sub-step count follows ``wc`` and ``mu``, a whole number: it jumps as ``wc`` moves);
- ``kelvin:N``: the library's contact (a Kelvin-Voigt damper switched on whole at the first sub-step in contact), its
  count held at ``N`` times the library's rule's (``h wc sqrt(1 + mu) <= H_WC_MAX``, 0.1) at the answer, at every
  point of the scan;
- ``veps:F``: the library's model with the motor friction's smoothing speed ``veps`` held at ``F`` times the answer's;
- ``newton:N``: the ramped force at the library's count with ``N`` Newton steps of the motor's implicit velocity step (the
  library's: 2);
- ``ramp:N``: the same with the damper ramped in over one sub-step's penetration (its closing speed at most
  ``pen / h``; tried as the library's contact in hornans20 and not landed: docs/online.md, "(issue 15, hornans20)").

Per scan: the cost's span over the scan (max over min - 1), its roughness (the RMS of the cost about a local cubic in
``x`` over :data:`ROUGH_WINDOW` points, Savitzky-Golay, over the answer's cost), the strict local minima, the largest move between neighbouring
points (over the answer's cost) and the sub-step counts the native scan crossed. A cost smooth in the
parameter has one or two minima and a roughness far below its span; a cost that jumps where the count changes is
the discretisation, not the data. The machine may be shared: the load is printed.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy.signal import savgol_filter

from servoid.drivers.twin import preset
from servoid.ident._jit import jit
from servoid.ident.models import servo_loop as sl
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import horn_contact as hc
from servoid.ident.offline import loop_fit as lf

#: Truth plays (c1 + c2) of the horn presets, rad (the twins' own: one owner of the fact).
#: Points of the local cubic the roughness is read about (Savitzky-Golay).
ROUGH_WINDOW = 15
TRUTH = {name: preset(name).play_rad for name in ("sts3215", "xm430")}


#: The contact's sub-step rule (``h wc sqrt(1 + mu) <= H_WC_MAX``): the held counts' unit.
HELD_UNIT = sl.H_WC_MAX


@jit
def _force(x: float, yl: float, v: float, w: float, c1: float, c2: float, k2: float, c: float, h: float,
           ramp: bool) -> float:  # fmt: skip
    """The contact's force: the library's Kelvin-Voigt (:func:`~servoid.ident.models.servo_loop._contact_force`: the
    damper switched on whole at the first sub-step in contact), or with ``ramp`` the damper ramped in over one
    sub-step's penetration (its closing speed at most ``pen / h``: 0 at zero penetration, continuous)."""
    if not ramp:
        return sl._contact_force(x, yl, v, w, c1, c2, k2, c)
    d = x - yl
    f = 0.0
    if d > c1:
        pen = d - c1
        f = max(k2 * pen + c * min(v - w, pen / h), 0.0)
    elif d < -c2:
        pen = d + c2
        f = min(k2 * pen + c * max(v - w, pen / h), 0.0)
    return f


@jit
def _simulate_held(p: np.ndarray, u: np.ndarray, y0: float, period: float, mc: int, ramp: bool, newton: int,
                   y_out: np.ndarray) -> None:  # fmt: skip
    """The compliant-contact simulation (play in the loop) on ``mc`` sub-steps a host period, at every ``wc``, with
    ``newton`` Newton steps of the motor's implicit velocity step (the library's: 2)."""
    x, yl, v, z, w, _, vf = sl._at_rest(p, y0)
    kp, kv, ki, vmax, fc, fs, vs, veps, a0, c1, c2 = sl._loop_params(p)
    mu, al, wc, zeta = p[12], p[14], p[15], p[16]
    h = period / mc
    als, vls = sl._breakaway(p)
    k2, c = wc * wc, 2.0 * zeta * wc
    g, _ = sl._gains(p, h)
    for k in range(y_out.shape[0]):
        y_out[k] = yl
        r = u[k]
        for _ in range(mc):
            f = _force(x, yl, v, w, c1, c2, k2, c, h, ramp)
            vcmd, base = sl._command(x, yl, v, z, r, True, kp, kv, vmax, a0 - mu * f, h)
            base, kvf = sl._filtered(base, kv, vf, g, h)
            vn = v
            for _ in range(newton):
                vn = sl._newton(vn, base, kvf, fc, fs, vs, veps, h)
            vf = sl._filter_moved(vf, vn, g)
            x, yl, z, w = sl._contact_moved(x, yl, z, w, f, vcmd, vn, vf, ki, al, veps, h, als, vls)
            v = vn


def _vector(d: dict[str, float]) -> np.ndarray:
    """The kernel's parameter vector of the fit's values ``d`` (``play``, ``asym`` -> ``c1``, ``c2``)."""
    d = dict(d)
    asym = d.get("asym", 0.0)
    d["c1"] = d["play"] * (0.5 + asym)
    d["c2"] = d["play"] * (0.5 - asym)
    return np.array([d.get(name, 0.0) for name in sl.KERNEL_NAMES])


def _cost_held(u: np.ndarray, y: np.ndarray, period: float, d: dict[str, float], kept: np.ndarray, mc: int,
               ramp: bool, newton: int = 2) -> float:  # fmt: skip
    """The cost on ``kept`` with the contact's count held at ``mc`` (:func:`_simulate_held`)."""
    stop = int(np.flatnonzero(kept)[-1]) + 1
    out = np.empty(stop)
    _simulate_held(_vector(d), u, float(y[0]), period, mc, ramp, newton, out)
    r = out[kept[:stop]] - y[:stop][kept[:stop]]
    return float(r @ r)


def _count(period: float, d: dict[str, float]) -> int:
    """The contact's sub-steps a period by the library's rule at the kernel's ``kv`` (:data:`HELD_UNIT`)."""
    m = sl.substeps(period, d["kv"])
    return max(m, int(math.ceil(period * d["wc"] * math.sqrt(1.0 + d["mu"]) / HELD_UNIT)))


def _describe(x: np.ndarray, c: np.ndarray, base: float) -> str:
    smooth = savgol_filter(c, ROUGH_WINDOW, 3)
    rough = float(np.sqrt(np.mean((c - smooth) ** 2))) / base
    span = float(np.max(c) / np.min(c) - 1.0)
    minima = int(np.sum((c[1:-1] < c[:-2]) & (c[1:-1] < c[2:])))
    step = float(np.max(np.abs(np.diff(c)))) / base
    low = float(math.exp(x[int(np.argmin(c))]))
    return f"span {span:6.2%} rough {rough:6.3%} minima {minima:3d} max step {step:6.3%} lowest at {low:.3f}x"


def scan(
    u: np.ndarray, y: np.ndarray, kept: np.ndarray, period: float, truth: float, args: argparse.Namespace, tag: str
) -> None:
    cached = args.answers / f"{tag}.json" if args.answers else None
    if cached is not None and cached.exists():
        d = json.loads(cached.read_text())
        print(f"  the answer from {cached}: {d['play'] / truth - 1:+.1%}", flush=True)
    else:
        t0 = time.perf_counter()
        whole = lf.fit_loop(u, y, period, keep=kept, load=False)
        found = hc.with_horn(u, y, period, whole, kept)
        kept_horn = found is not whole and found.model.compliant
        print(f"  massless {whole.play / truth - 1:+.1%}, horn {'kept' if kept_horn else 'not kept'}"
              f"{f' {found.play / truth - 1:+.1%}' if kept_horn else ''} [{time.perf_counter() - t0:.1f} s]",
              flush=True)  # fmt: skip
        if not kept_horn:
            return
        d = hc._values(found.model)
        if cached is not None:
            cached.parent.mkdir(parents=True, exist_ok=True)
            cached.write_text(json.dumps(d))
    centre = float(np.mean(u))
    uc, yc = np.ascontiguousarray(u - centre), np.ascontiguousarray(y - centre)
    print(f"  the answer's horn: wc {d['wc']:.0f} zeta {d['zeta']:.3f} al {d['al']:.1f} mu {d['mu']:.3f}; "
          f"kv {d['kv']:.1f} fc {d['fc']:.2f} fs {d['fs']:.2f} vs {d['vs']:.4f} veps {d['veps']:.2e}", flush=True)  # fmt: skip
    mc0 = _count(period, d)
    base = lf._cost(uc, yc, period, PLAY_IN_LOOP, d, kept)
    x = np.linspace(-args.span, args.span, args.points)
    for name in args.params:
        for mode in args.modes:
            t1 = time.perf_counter()
            costs, counts = [], set()
            kind, _, times = mode.partition(":")
            for xi in x:
                di = dict(d, **{name: d[name] * math.exp(xi)})
                if kind == "veps":  # the library's model with the motor friction's smoothing speed times ``times``
                    costs.append(lf._cost(uc, yc, period, PLAY_IN_LOOP, dict(di, veps=d["veps"] * float(times)), kept))
                elif kind == "newton":  # the library's force and count, ``times`` Newton steps
                    native = int(sl.contact_substeps(period, sl.substeps(period, d["kv"]), di["mu"], di["wc"]))
                    costs.append(_cost_held(uc, yc, period, di, kept, native, True, int(times)))
                elif kind == "native":
                    costs.append(lf._cost(uc, yc, period, PLAY_IN_LOOP, di, kept))
                    counts.add(int(sl.contact_substeps(period, sl.substeps(period, d["kv"]), di["mu"], di["wc"])))
                else:
                    costs.append(_cost_held(uc, yc, period, di, kept, int(times) * mc0, kind == "ramp"))
            c = np.asarray(costs)
            label = f"{mode} ({int(times) * mc0})" if times and kind in ("kelvin", "ramp") else mode
            crossed = f" counts {min(counts)}-{max(counts)}" if counts else ""
            print(f"    {name:5s} {label:14s} {_describe(x, c, base)}{crossed} [{time.perf_counter() - t1:.0f} s]",
                  flush=True)  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=Path, nargs="+", help="online.py --keep run directories")
    parser.add_argument("--ends", type=float, nargs="+", default=[0.0], help="fast part's s; 0: all")
    parser.add_argument("--params", nargs="+", default=["wc", "play", "al", "zeta"])
    parser.add_argument("--span", type=float, default=0.1, help="the scan's half width, ln units")
    parser.add_argument("--points", type=int, default=161)
    parser.add_argument("--modes", nargs="+", default=["native", "kelvin:1", "ramp:1", "kelvin:2", "ramp:2"],
                        help="native, or kelvin:N / ramp:N (the count held at N x the old rule's at the answer)")  # fmt: skip
    parser.add_argument("--answers", type=Path, default=None, help="keep / read each record's answer here (json)")
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from horn_profile import live_ends

    for run, end, (u, y, kept, period, name) in live_ends(args.runs, args.ends):
        scan(u, y, kept, period, TRUTH[name], args, f"{run.name}-{end:g}")
    print(f"machine load (1 min) at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
