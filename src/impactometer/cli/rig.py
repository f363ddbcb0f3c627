"""``impactometer rig show``: a stand as the TOML file to start a stand of your own from."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..outputs import check_file, write_atomically
from ..rig import PRESETS, get_rig, toml_text
from .app import OVERWRITE, App, app, console, given
from .simulate import ContactOpt

rig_app = App(help="Stands: write a built-in stand (or a stand file) as TOML, to start a stand of your own from.")
app.add_typer(rig_app, name="rig")


def stand_file_text(name: str, contact: str | None = None) -> str:
    """The TOML text ``rig show`` writes for the stand ``name`` (a preset or a TOML file): a comment saying how to
    use it, then the stand's every section and value."""
    with given(contact=contact):  # the stand is an argument: the core's message names it as it is
        stand = get_rig(name, contact=contact)
    command = f"impactometer rig show {name}" + (f" --contact {contact}" if contact else "")
    return (f"# The stand {stand.name}, written by `{command}`: edit it into your own (under a name of\n"
            "# its own) and pass it as --rig FILE. A section or key left out takes the built-in drop-stand's value.\n"
            "# SI units: kg, m, m³, Pa (rated_pressure_gauge: gauge), N, N/m, N·s/m, K, J/(kg·K), m²; see\n"
            "# docs/simulation.md for what each value is.\n"
            + toml_text(stand))


@rig_app.command("show")
def show(
    stand: Annotated[str, typer.Argument(metavar="STAND", help=f"A built-in stand ({', '.join(PRESETS)}) or a "
                                                              "TOML file.")] = "drop-stand",
    out: Annotated[Path | None, typer.Option("--out", metavar="FILE",
                                             help="Write the TOML to FILE (.toml) instead of standard output.")] = None,
    contact: ContactOpt = None,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite an existing FILE.")] = False,
) -> None:
    """Print a stand as TOML, or write it with --out: the file to edit into a stand of your own, then read with
    --rig FILE by every command."""
    if out is not None:
        out = check_file(out, "--out", overwrite=overwrite, extensions=(".toml",))
    text = stand_file_text(stand, contact)
    if out is None:
        typer.echo(text, nl=False)
        return
    write_atomically(out, lambda temporary: temporary.write_text(text, encoding="utf-8"), overwrite=overwrite)
    console.print(f"stand {stand} written to {out}", highlight=False, markup=False)
