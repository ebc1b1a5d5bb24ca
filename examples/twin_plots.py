"""Draw what each physical twin does, for docs/twins.md, and print its datasheet table.

    .venv/bin/python examples/twin_plots.py [--out docs/img]

One figure per preset (``twin-<name>.png``), six panels:

1. a small and a large step (the output encoder, the motor side of the gear, the set point);
2. the large step's duty and current: saturation;
3. the friction stall: a step of a few counts, with the factory gains and
   (for firmware without an integrator) with an integral gain added;
4. the play at reversals: a slow sine, output against the motor side;
5. quantisation: a slow ramp, the encoder's reading against the true angle;
6. the stick state: when motor and load were stuck during the sine.

Then a markdown table of the vendor's figures against the twin's.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from servoid.drivers.twin import Twin, preset, preset_names  # noqa: E402
from servoid.drivers.twin.figures import measure  # noqa: E402
from servoid.drivers.twin.presets import PUBLISHED  # noqa: E402

HOST_S = 0.0005  # the plots' host period: 2 kHz, finer than any drive's behaviour of interest


def run(name: str, u: np.ndarray, **overrides):
    twin = Twin(preset(name, **overrides), seed=1)
    twin.enable()
    return twin, twin.sample(u, HOST_S)


def steps(name: str, ax_pos, ax_drive) -> None:
    n = int(0.4 / HOST_S)
    small, large = 0.02, 0.5
    for amp, style in ((small, "-"), (large, "--")):
        u = np.r_[np.zeros(20), np.full(n, amp)]
        twin, rec = run(name, u)
        t = rec.t_s * 1e3
        ax_pos.plot(t, rec.y / amp, style, color="C0", label=f"output / {amp:g} rad")
        ax_pos.plot(t, rec.true_gear_side_rad / amp, style, color="C1", lw=0.8, label=f"motor side / {amp:g} rad")
        if amp == large:
            ax_drive.plot(t, rec.duty, color="C2", label="duty")
            ax_drive.plot(
                t,
                rec.current_a / max(1e-9, np.max(np.abs(rec.current_a))),
                color="C3",
                lw=0.8,
                label=f"current / {np.max(np.abs(rec.current_a)):.2g} A",
            )
            c = twin.counters
            ax_drive.set_title(
                f"{large:g} rad step: saturated {c.saturated_share:.0%} of ticks, "
                f"current-limited {c.current_limited_ticks}",
                fontsize=8,
            )
    ax_pos.axhline(1.0, color="k", lw=0.5)
    ax_pos.set_title("steps (normalised)", fontsize=9)
    ax_pos.set_xlabel("ms")
    ax_pos.legend(fontsize=6)
    ax_drive.set_xlabel("ms")
    ax_drive.legend(fontsize=6)


def stall(name: str, ax) -> None:
    p = preset(name)
    counts = 3 if p.output_counts_per_rev <= 4096 else 30
    step = counts * 2 * np.pi / p.output_counts_per_rev
    u = np.r_[np.zeros(20), np.full(int(1.0 / HOST_S), step)]
    variants = [("factory gains", {})]
    if p.firmware != "cascade":
        # an integral gain within the control table's range (Dynamixel 0..16383, Feetech 0..254)
        gain = 400.0 if p.firmware == "dynamixel_position" else 20.0
        variants.append((f"with I gain {gain:g}", {"pos_i": gain}))
    for label, overrides in variants:
        twin, rec = run(name, u, **overrides)
        ax.plot(rec.t_s, (rec.true_gear_side_rad - rec.true_gear_side_rad[0]) / step, label=f"motor side, {label}")
        ax.plot(rec.t_s, rec.y / step, lw=0.8, label=f"output, {label}")
    ax.axhline(1.0, color="k", lw=0.5)
    inside = " (within half the play)" if step < preset(name).play_rad / 2 else ""
    ax.set_title(f"friction stall: a {counts}-count step{inside}", fontsize=9)
    ax.set_xlabel("s")
    ax.set_ylabel("/ step")
    ax.legend(fontsize=6)


def reversals(name: str, ax_loop, ax_stick) -> None:
    t = np.arange(int(2.0 / HOST_S)) * HOST_S
    amp = 0.05
    u = amp * np.sin(2 * np.pi * 1.0 * t)
    twin, rec = run(name, u)
    half = len(u) // 2  # the second period: past the start-up
    ax_loop.plot(rec.true_gear_side_rad[half:] * 1e3, rec.y[half:] * 1e3, lw=0.8)
    ax_loop.set_xlabel("motor side of the gear, mrad")
    ax_loop.set_ylabel("output encoder, mrad")
    ax_loop.set_title(f"1 Hz sine: play {twin.truth.play_rad * 1e3:.2f} mrad", fontsize=9)
    # the stick state over the same run, from the counters of short runs
    twin = Twin(preset(name), seed=1)
    twin.enable()
    stuck_m, stuck_l = [], []
    for v in u[::10]:
        twin.command(v)
        before = twin.counters
        twin.advance(10 * HOST_S)
        after = twin.counters
        stuck_m.append((after.stuck_motor_s - before.stuck_motor_s) / (10 * HOST_S))
        stuck_l.append((after.stuck_load_s - before.stuck_load_s) / (10 * HOST_S))
    tt = t[::10]
    ax_stick.plot(tt, u[::10] / amp, color="k", lw=0.5, label="set point / amplitude")
    ax_stick.fill_between(tt, 0, stuck_m, step="post", alpha=0.4, label="motor stuck")
    ax_stick.fill_between(tt, 0, np.array(stuck_l) * -1, step="post", alpha=0.4, label="load stuck (down)")
    ax_stick.set_title("stick phases at the reversals", fontsize=9)
    ax_stick.set_xlabel("s")
    ax_stick.legend(fontsize=6)


def quantisation(name: str, ax) -> None:
    step = Twin(preset(name)).truth.output_rad_per_count
    # first a move of 0.05 rad, so that the gear is in contact, then a slow ramp over a dozen counts
    settle = int(0.3 / HOST_S)
    u = np.r_[np.full(settle, 0.05), 0.05 + np.linspace(0, 12 * step, int(1.0 / HOST_S))]
    twin, rec = run(name, u)
    base = np.round(rec.y[settle] / step)
    ax.plot(rec.t_s[settle:], rec.true_load_rad[settle:] / step - base, lw=0.8, label="true output angle")
    ax.step(rec.t_s[settle:], rec.y[settle:] / step - base, where="post", label="output encoder")
    ax.set_title(f"quantisation: {2 * np.pi / step:.0f} counts/rev", fontsize=9)
    ax.set_xlabel("s")
    ax.set_ylabel("counts from the start of the ramp")
    ax.legend(fontsize=6)


def figure(name: str, out: Path) -> Path:
    fig, axes = plt.subplots(2, 3, figsize=(13, 7))
    steps(name, axes[0, 0], axes[0, 1])
    stall(name, axes[0, 2])
    reversals(name, axes[1, 0], axes[1, 2])
    quantisation(name, axes[1, 1])
    fig.suptitle(f"{name}: {preset(name).description}", fontsize=10)
    fig.tight_layout()
    path = out / f"twin-{name}.png"
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def datasheet_table() -> str:
    rows = ["| preset | figure | published | twin | source |", "|---|---|---|---|---|"]
    for name in preset_names():
        pub = PUBLISHED[name]
        fig = measure(preset(name))
        for label, published, twin, fmt in (
            ("no-load speed, rpm", pub.no_load_speed_rpm, fig.no_load_speed_rpm, "{:.1f}"),
            ("stall torque, N m", pub.stall_torque_nm, fig.stall_torque_nm, "{:.2f}"),
            ("stall current, A", pub.stall_current_a, fig.stall_current_a, "{:.2f}"),
            ("resolution, counts/rev", pub.output_cpr, fig.output_cpr, "{:.0f}"),
        ):
            if published is not None:
                rows.append(f"| {name} | {label} | {fmt.format(published)} | {fmt.format(twin)} | {pub.source} |")
    return "\n".join(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("docs/img"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for name in preset_names():
        print(figure(name, args.out))
    print(datasheet_table())


if __name__ == "__main__":
    main()
