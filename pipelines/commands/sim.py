"""beambench sim: simulate one scene and write it as NetCDF (design.md, "A simulation on
its own")."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from pipelines.commands._args import (
    add_damping_law_argument,
    add_rig_argument,
    damping_law_from_args,
    rig_from_args,
)
from pipelines.errors import BeambenchError
from pipelines.paths import check_writable_output, refuse_aliases
from pipelines.results.sim_dataset import (
    check_output_path,
    modes_dataset,
    sim_dataset,
    write_dataset,
)
from pipelines.rig import Rig
from sim import scenes
from sim.beam import BeamProperties
from sim.errors import ModelNotAvailable
from sim.models.registry import MODELS
from sim.statics import table2_comparison

SCENES = ("reciprocating", "static", "free-decay", "spin-up", "falling-body", "modes", "linkage")

DEFAULT_MASS_KG = {"static": 0.149, "free-decay": 0.1}
DEFAULT_DURATION_S = {"reciprocating": 10.0, "free-decay": 10.0, "spin-up": 30.0}
DEFAULT_RATE_HZ = {"spin-up": 100.0}  # the bench scenes: 400 Hz

# Work is bounded before it starts (the error names the estimated cost):
MAX_DURATION_S = 1200.0  # about 1100 crank cycles at the bench's 0.92 Hz; 20 min of run
MAX_OUTPUT_RATE_HZ = 20000.0  # 50x the DAQ's 400 Hz
MAX_OUTPUT_SAMPLES = 2_000_000  # times x (gauges + stations) float64: ~0.5 GB of results
RTOL_RANGE = (1e-10, 0.1)  # below 1e-10 the error is round-off and steps grow as rtol^-1/5
MAX_OMEGA_RAD_S = 50.0  # 5x the benchmark's fastest spin-up (10 rad/s); steps grow with it
MAX_MASS_KG = 10.0  # a tip mass 70 times the beam's 0.14 kg
MAX_DAMPING = (1e3, 10.0)  # a0 (1/s), a1 (s): as the rig's limits
# wall seconds per simulated second, measured on the 2-core development machine (README
# "Speed and error"; exact FE with 8 elements, the slowest the auto model picks)
SOLVE_S_PER_S = {"rigid": 0.001, "modal": 0.006, "auto": 0.14, "fe": 0.14}


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", choices=SCENES)
    add_rig_argument(p)
    p.add_argument("--model", choices=MODELS, default="auto")
    p.add_argument("--out", metavar="FILE.nc", default=None)
    p.add_argument(
        "--drive",
        choices=("paper", "fourbar"),
        default="paper",
        help="reciprocating: the paper's sinusoid (Eq. 53) or the true four-bar output",
    )
    p.add_argument(
        "--damping",
        nargs=2,
        type=_finite,
        metavar=("A0", "A1"),
        default=None,
        help="proportional damping a0 (1/s), a1 (s); default: the rig's",
    )
    add_damping_law_argument(p)
    p.add_argument(
        "--duration",
        type=_finite,
        metavar="S",
        default=None,
        help="simulated time, s (reciprocating 10, free-decay 10, spin-up 30, falling-body 2; "
        f"at most {MAX_DURATION_S:g} s and {MAX_OUTPUT_SAMPLES:g} output samples)",
    )
    p.add_argument(
        "--mass",
        type=_finite,
        metavar="KG",
        default=None,
        help=f"static / free-decay tip mass, kg (default 0.149 / 0.1; at most {MAX_MASS_KG:g})",
    )
    p.add_argument(
        "--omega",
        type=_finite,
        metavar="RAD_S",
        default=4.0,
        help="spin-up: final hub speed, rad/s (the benchmark uses 4 and 10; at most "
        f"{MAX_OMEGA_RAD_S:g})",
    )
    p.add_argument(
        "--no-stiffening",
        action="store_true",
        help="spin-up, modal: leave out the centrifugal stiffening (diverges)",
    )
    p.add_argument(
        "--n-modes", type=int, default=None, metavar="N", help="modal model: number of modes"
    )
    p.add_argument(
        "--nonlinear",
        action="store_true",
        help="modal model: keep the geometric nonlinearity to third order",
    )
    p.add_argument(
        "--rtol",
        type=_finite,
        default=None,
        help="tolerance of the dynamic model (default: the model's own; modal 1e-6, auto 1e-4; "
        f"within {RTOL_RANGE[0]:g}..{RTOL_RANGE[1]:g})",
    )
    p.add_argument(
        "--output-rate",
        type=_finite,
        metavar="HZ",
        default=None,
        help="output samples per second (400 for the bench scenes, 100 for spin-up; at most "
        f"{MAX_OUTPUT_RATE_HZ:g})",
    )
    p.add_argument(
        "--target-log-decrement",
        type=_finite,
        default=None,
        help="free-decay: identify a0 = a1 reproducing this measured decrement",
    )
    p.add_argument("--json", action="store_true", help="linkage: print JSON")
    p.add_argument(
        "--table2",
        action="store_true",
        help="static: print the paper's Table 2 beside linear theory and the elastica",
    )


def _positive(name: str, value: float | None) -> None:
    if value is not None and value <= 0.0:
        raise BeambenchError(f"{name} must be positive, got {value!r}")


def _check(args: argparse.Namespace) -> None:
    if args.mass is not None and args.mass < 0.0:
        raise BeambenchError(f"--mass must be non-negative, got {args.mass!r} kg")
    _positive("--duration", args.duration)
    _positive("--rtol", args.rtol)
    _positive("--output-rate", args.output_rate)
    _positive("--target-log-decrement", args.target_log_decrement)
    if args.damping is not None and min(args.damping) < 0.0:
        raise BeambenchError(f"--damping values must be non-negative, got {args.damping!r}")
    if args.n_modes is not None and not 1 <= args.n_modes <= 40:
        raise BeambenchError(f"--n-modes must be between 1 and 40, got {args.n_modes!r}")
    _check_bounds(args)


def _at_most(name: str, value: float | None, limit: float, unit: str) -> None:
    if value is not None and value > limit:
        raise BeambenchError(f"{name} must be at most {limit:g} {unit}, got {value:g}")


def _check_bounds(args: argparse.Namespace) -> None:
    """Refuse work beyond the limits the help states, naming its estimated cost."""
    _at_most("--mass", args.mass, MAX_MASS_KG, "kg (a tip mass 70 times the beam's)")
    _at_most("--omega", args.omega, MAX_OMEGA_RAD_S, "rad/s (5x the benchmark's 10 rad/s)")
    _at_most("--output-rate", args.output_rate, MAX_OUTPUT_RATE_HZ, "Hz")
    _at_most("--target-log-decrement", args.target_log_decrement, 10.0, "(a 1e-4 amplitude ratio)")
    if args.damping is not None:
        _at_most("--damping A0", args.damping[0], MAX_DAMPING[0], "1/s")
        _at_most("--damping A1", args.damping[1], MAX_DAMPING[1], "s")
    if args.rtol is not None and not RTOL_RANGE[0] <= args.rtol <= RTOL_RANGE[1]:
        raise BeambenchError(
            f"--rtol must be within {RTOL_RANGE[0]:g}..{RTOL_RANGE[1]:g}, got {args.rtol:g} "
            "(below 1e-10 a double-precision solve gains nothing and its steps grow as "
            "rtol^-1/5 without end)"
        )
    duration = args.duration if args.duration is not None else DEFAULT_DURATION_S.get(args.scene)
    if duration is None:
        return
    rate = args.output_rate or DEFAULT_RATE_HZ.get(args.scene, 400.0)
    samples = duration * rate
    solve_s = duration * SOLVE_S_PER_S.get(args.model, SOLVE_S_PER_S["fe"])
    cost = (
        f"{samples:.3g} output samples at {rate:g} Hz and about {human_s(solve_s)} of "
        f"solving with --model {args.model}"
    )
    if duration > MAX_DURATION_S:
        raise BeambenchError(
            f"--duration {duration:g} s would take {cost}; at most {MAX_DURATION_S:g} s "
            "(about 1100 crank cycles at 0.92 Hz) is simulated"
        )
    if samples > MAX_OUTPUT_SAMPLES:
        raise BeambenchError(
            f"--duration {duration:g} s at --output-rate {rate:g} Hz would take {cost}; "
            f"at most {MAX_OUTPUT_SAMPLES:g} output samples are written"
        )


def human_s(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _kw(args: argparse.Namespace, **defaults: Any) -> dict[str, Any]:
    out = dict(defaults)
    if args.duration is not None:
        out["duration_s"] = args.duration
    if args.n_modes is not None:
        out["n_modes"] = args.n_modes
    if args.output_rate is not None:
        out["output_rate_hz"] = args.output_rate
    return out


def _run_scene(args: argparse.Namespace, rig: Rig) -> scenes.SceneRun:
    gauges = tuple(rig.gauges.positions_m)
    a0a1 = args.damping
    if args.scene == "reciprocating":
        a0, a1 = a0a1 if a0a1 is not None else (rig.damping.a0_per_s, rig.damping.a1_s)
        return scenes.reciprocating(
            rig.linkage,
            rig.beam,
            rig.drive,
            drive=args.drive,
            a0_per_s=a0,
            a1_s=a1,
            model=args.model,
            gauge_positions_m=gauges,
            rtol=args.rtol,
            nonlinear=args.nonlinear,
            damping_law=damping_law_from_args(args, rig),
            **_kw(args),
        )
    if args.scene == "static":
        mass = DEFAULT_MASS_KG["static"] if args.mass is None else args.mass
        kw = {"n_modes": args.n_modes} if args.n_modes is not None else {}
        return scenes.static(
            rig.beam, mass_kg=mass, model=args.model, gauge_positions_m=gauges, **kw
        )
    if args.scene == "free-decay":
        mass = DEFAULT_MASS_KG["free-decay"] if args.mass is None else args.mass
        if mass <= 0.0:
            raise BeambenchError("--mass must be positive for the free-decay scene")
        a0, a1 = a0a1 if a0a1 is not None else (None, None)
        model = "modal" if args.model == "auto" else args.model
        return scenes.free_decay(
            rig.beam,
            rig.damping,
            mass_kg=mass,
            a0_per_s=a0,
            a1_s=a1,
            model=model,
            gauge_positions_m=gauges,
            target_log_decrement=args.target_log_decrement,
            **_kw(args),
        )
    if args.scene == "spin-up":
        _positive("--omega", args.omega)
        return scenes.spin_up(
            omega_rad_s=args.omega,
            model=args.model,
            stiffening=not args.no_stiffening,
            rtol=args.rtol,
            nonlinear=args.nonlinear,
            **_kw(args),
        )
    if args.scene == "falling-body":
        return scenes.falling_body(rig.beam, gauge_positions_m=gauges, **_kw(args))
    raise AssertionError(args.scene)  # pragma: no cover


def _print_linkage(info: dict[str, Any], as_json: bool) -> None:
    if as_json:
        print(json.dumps(info, sort_keys=True))
        return
    deg = math.degrees
    print(f"grashof: {info['grashof']}")
    for end in ("min", "max"):
        print(
            f"rocker {end} {deg(info[f'rocker_{end}_rad']):.3f} deg "
            f"at crank {deg(info[f'crank_at_{end}_rad']):.3f} deg "
            f"(paper: {deg(info[f'paper_rocker_{end}_rad']):.3f} deg "
            f"at {deg(info[f'paper_crank_at_{end}_rad']):.0f})"
        )
    print(f"range {deg(info['rocker_range_rad']):.3f} deg (paper: 87.876 deg)")
    print(
        f"transmission angle {deg(info['transmission_angle_min_rad']):.3f} .. "
        f"{deg(info['transmission_angle_max_rad']):.3f} deg"
    )


def _print_table2(rig: Rig) -> None:
    rows = table2_comparison(BeamProperties.from_config(rig.beam), rig.gauges.positions_m)
    print(
        "Table 2 tip deflection (mm): paper measured / paper theoretical / FLXDYN | "
        "PL^3/3EI / elastica | paper theory mm per kg, implied mass kg"
    )
    for r in rows:
        print(
            f"{r['mass_kg']:.3f} kg: {r['measured_tip_mm']:.2f} / "
            f"{r['paper_theoretical_tip_mm']:.2f} / {r['flxdyn_tip_mm']:.2f} | "
            f"{r['linear_tip_mm']:.2f} / {r['elastica_tip_mm']:.2f} | "
            f"{r['paper_theoretical_mm_per_kg']:.1f}, {r['implied_mass_kg']:.4f}"
        )


def run(args: argparse.Namespace) -> int:
    refuse_aliases({"--out": args.out}, {"--rig": args.rig})
    rig = rig_from_args(args)
    _check(args)
    if args.out is not None:
        try:
            check_output_path(args.out)
        except ValueError as exc:
            raise BeambenchError(f"--out {exc}") from None
        check_writable_output(args.out, "--out")
    if args.scene == "linkage":
        _print_linkage(scenes.linkage(rig.linkage), args.json)
        return 0
    if args.table2:
        if args.scene != "static":
            raise BeambenchError("--table2 applies to the static scene only")
        _print_table2(rig)
    try:
        if args.scene == "modes":
            info = scenes.modes(rig.beam, **({"n_modes": args.n_modes} if args.n_modes else {}))
            ds = modes_dataset(info, rig_json=rig.to_json())
            summary = (
                "modes: " + ", ".join(f"{f:.3f}" for f in ds["natural_frequency"].values) + " Hz"
            )
        else:
            scene_run = _run_scene(args, rig)
            ds = sim_dataset(
                scene_run.result, scene=args.scene, rig_json=rig.to_json(), extras=scene_run.extras
            )
            res = scene_run.result
            peak = float(abs(res.tip_lateral_m).max()) if res.tip_lateral_m.size else 0.0
            summary = (
                f"{args.scene}: model {res.model}, wall time {res.wall_time_s:.4f} s, "
                f"max |tip_lateral| {peak * 1e3:.4f} mm"
            )
            if args.scene == "free-decay":
                ex = scene_run.extras
                summary += (
                    f", log decrement {ex['log_decrement']:.5f}, zeta {ex['damping_ratio']:.5f}, "
                    f"identified a0 = a1 = {ex['identified_a0_per_s']:.6g}"
                )
    except ModelNotAvailable as exc:
        raise BeambenchError(f"--model {args.model}: {exc}") from None
    except ValueError as exc:
        raise BeambenchError(f"{args.scene}: {exc}") from None
    if args.out is not None:
        try:
            write_dataset(ds, args.out)
        except (OSError, ValueError) as exc:
            raise BeambenchError(f"--out {args.out}: cannot write: {exc}") from None
    if args.out is None or sys.stdout.isatty():
        print(summary + (f" -> {args.out}" if args.out else ""))
    return 0
