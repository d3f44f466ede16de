"""``printapp bench``: speed against accuracy, beside the peers."""

from pathlib import Path
from typing import Annotated

import typer

from printapp.cli.app import app, out, wrote


@app.command()
def bench(
    stages: Annotated[list[str] | None, typer.Argument(help="Stages to run [default: all].")] = None,
    out_dir: Annotated[Path, typer.Option("--out", "-o", help="Folder for bench.json and charts.")] = Path(
        "bench-out"
    ),
    repeats: Annotated[int, typer.Option(min=1, max=100, help="Timed repeats per setting (median).")] = 5,
) -> None:
    """Measure speed against accuracy; print a table, write JSON and PNG charts."""
    from printapp.bench import STAGES, run_bench

    names = list(stages) if stages else list(STAGES)
    wrote(run_bench(names, out_dir, repeats=repeats, console=out))
