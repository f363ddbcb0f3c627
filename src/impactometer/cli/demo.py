"""``impactometer demo``: the whole chain on the built-in impact -- simulate, sense, identify, absorb."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from ..errors import IdentificationError, ParameterError
from ..outputs import check_file, check_folder, save_figure
from ..rig import ABSORPTION_RIG, Scenario, get_rig
from .app import OVERWRITE, announce_compilation, app, console, with_uncertainty
from .control import metrics_table
from .simulate import summary_table

NOISE = 0.02  # sensor noise of the demo, fraction of each channel's RMS
SAMPLE_RATE = 50e3  # [Hz]


@app.command()
def demo(
    out: Annotated[Path, typer.Option("--out", metavar="DIR", help="Output folder of the figures (impact.png, "
                                                                   "absorb.png); created, replaced only with "
                                                                   "--overwrite.")]
    = Path("impactometer-demo"),
    absorb: Annotated[bool, typer.Option("--absorb/--no-absorb", help="Also run the closed loop identify → "
                                                                      "control (a second; 15-40 s on a first run, "
                                                                      "which compiles it).")] = True,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Replace the figures of an existing output folder.")]
    = False,
) -> None:
    """Built-in impact (30 kg from 0.2 m onto the stand at 200 kPa): simulate, identify, absorb, draw."""
    from ..model import simulate as run_simulation

    if out.exists() and not (overwrite and out.is_dir()):
        raise ParameterError(f"--out: {str(out)!r} exists; pass --overwrite to replace the demo's figures in it, or "
                             "choose another folder with --out DIR" if out.is_dir() else
                             f"--out: {str(out)!r} is a file; expected a folder for the demo's figures")
    check_folder(out, "--out")
    out.mkdir(parents=True, exist_ok=True)
    stand = get_rig()
    scenario = Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=200e3, gravity=stand.gravity)
    impact_png, absorb_png = out / "impact.png", out / "absorb.png"
    for figure in (impact_png, absorb_png):
        check_file(figure, "--out", overwrite=True)
    with announce_compilation("1. simulating the drop"):
        result = run_simulation(scenario, stand, duration=0.1, sample_rate=SAMPLE_RATE)
        table, pulses = summary_table(result, "1. simulation: 30 kg from 0.2 m onto the drop stand at 200 kPa")
    console.print(table)
    save_figure(result.plot(pulses=pulses), impact_png)
    console.print(f"figure written to {impact_png}\n")

    with announce_compilation("2. identifying M1 and V0 from the simulated sensors"):
        table = identification_table(scenario, stand)
    console.print(table)
    if absorb:
        from ..control.loop import absorb as run_absorb

        with announce_compilation(f"3. closed loop on {ABSORPTION_RIG}: identify, then control valve Z with each "
                                  "strategy", compile_time="about 15-40 s"):
            absorbed = run_absorb(scenario, get_rig(ABSORPTION_RIG), strategy="all", noise=NOISE, seed=0)
        metrics = metrics_table(absorbed)
        metrics.title = f"\n3. adaptive absorption (the paper's Fig. 10b), {NOISE:.0%} sensor noise: {metrics.title}"
        console.print(metrics)
        save_figure(absorbed.plot(), absorb_png)
        console.print(f"figure written to {absorb_png}")


def identification_table(scenario, stand) -> Table:
    """Peak-to-peak (paper, robust) and model-based identification of ``scenario`` from simulated sensors with
    noise, next to the truth."""
    from ..identify.peak_to_peak import identify
    from ..sensors import record

    recording = record(scenario, stand, sample_rate=SAMPLE_RATE, duration=0.1, noise=NOISE, seed=0,
                       pre_trigger=0.02)
    table = Table(title=f"2. identification from force + acceleration at {SAMPLE_RATE / 1e3:g} kHz, "
                        f"{NOISE:.0%} noise (truth: M1 = {scenario.mass:g} kg, V0 = {scenario.velocity:.3f} m/s)")
    for column in ("method", "M1 [kg]", "error [%]", "V0 [m/s]", "error [%]", "E [J]",
                   "available at [ms after contact]"):
        table.add_column(escape(column), justify="left" if column == "method" else "right",
                         no_wrap=column in ("method", "M1 [kg]", "V0 [m/s]"))
    answers = []
    notes = []
    for variant in ("paper", "robust"):
        try:
            found = identify(recording, variant=variant)
        except IdentificationError as exc:
            table.add_row(variant, f"failed: {exc}", "", "", "", "", "")
            continue
        if variant == "robust" and found.early is not None:
            answers.append(("robust, early", found.early))
        elif variant == "robust":
            notes.append(f"robust, early: none -- {found.early_reason}; refused rather than answered far off, the "
                         "final answer rests on the turning points of stage B")
        answers.append((variant if variant == "paper" else "robust, final", found))
    from ..identify.model_fit import identify as identify_model
    from ..identify.model_fit.streaming import CADENCE

    try:  # the whole record fitted with the stand model, the contact law chosen by BIC
        model = identify_model(recording, rig=stand)
        answers.append((f"model ({model.details.get('contact_law')})", model))
    except IdentificationError as exc:
        table.add_row("model", f"failed: {exc}", "", "", "", "", "")
    first = first_stream_answer(recording, stand)
    if first is not None:
        answers.append((f"model stream, first ({first.details.get('contact_law')})", first))
        notes.append(f"model stream, first: the stand's answer from the first {first.details['window_ms']:.3g} ms "
                     "of contact, σ with the stand's parameters held at its values; updates follow every "
                     f"{CADENCE * 1e3:g} ms (impactometer stream --method model)")
    answers.sort(key=lambda item: item[1].available_at)  # the simulated clock starts contact at 0
    for label, found in answers:
        table.add_row(label, with_uncertainty(found.mass, found.mass_std),
                      f"{100 * (found.mass / scenario.mass - 1):+.1f}",
                      with_uncertainty(found.velocity, found.velocity_std),
                      f"{100 * (found.velocity / scenario.velocity - 1):+.1f}", f"{found.energy:.1f}",
                      f"{found.available_at * 1e3:.1f}")
    cautions = [f"paper: caution: {found.details['caution']}" for _, found in answers if found.details.get("caution")]
    if cautions or notes:
        table.caption = "\n".join(cautions + notes)
    return table


def first_stream_answer(recording, stand):
    """The model stream's first answer on ``recording`` (replayed in 64-sample chunks until it comes), or None
    when the stream gives none before the record ends."""
    from ..identify.model_fit.streaming import ModelStream

    stream = ModelStream(recording.sample_rate, start_time=recording.start_time, metadata=recording.metadata,
                         rig=stand)
    f, a = recording.contact_force, recording.piston_acceleration
    for k in range(0, f.size, 64):
        found = stream.push(f[k:k + 64], a[k:k + 64])
        if found:
            return found[0]
    return None
