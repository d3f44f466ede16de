"""``printapp solve`` (appearance targets to a printable relief; ``--reachable``: what the printer can
reach) and ``printapp sweep`` (variants of a design on Dask)."""

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.text import Text

from printapp.cli.app import ForceOption, QuietOption, app, err, out, warn, wrote

WorkersOption = Annotated[
    int,
    typer.Option(
        "--workers",
        min=0,
        max=256,
        help="Dask worker processes on this machine (0: in this process, no Dask).",
    ),
]
SchedulerOption = Annotated[
    str | None,
    typer.Option("--scheduler", help="Address of a running Dask scheduler (tcp://HOST:PORT) to use instead."),
]


@contextmanager
def _bar(label: str, quiet: bool) -> Iterator[Any]:
    """A progress bar on stderr: ``update(done, total, cached)`` moves it."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    progress = Progress(
        TextColumn("{task.description}"),
        BarColumn(bar_width=30),
        MofNCompleteColumn(),
        TextColumn("{task.fields[note]}"),
        TimeElapsedColumn(),
        console=err,
        disable=quiet,
    )
    task = progress.add_task(label, total=None, note="")

    def update(done: int, total: int, cached: int) -> None:
        progress.update(
            task, completed=done, total=total, note=f"({cached} from the cache)" if cached else ""
        )

    with progress:
        yield update


@contextmanager
def _status(quiet: bool) -> Iterator[Any]:
    """A status line on stderr: ``say(text)`` replaces it."""
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    progress = Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), console=err,
                        disable=quiet)  # fmt: skip
    task = progress.add_task("solve: starting the workers", total=None)
    with progress:
        yield lambda text: progress.update(task, description=f"solve: {text}")


def _targets_table(outcome: Any) -> None:
    out.print(f"  {'target':<34} {'achieved (traced)':>18} {'surrogate':>10} {'gap':>8}")
    for name, (lo, hi) in outcome.targets.items():
        achieved = outcome.achieved.get(name)
        shown = f"{achieved:.2f}" if achieved is not None else "refused"
        surrogate = outcome.surrogate.get(name)
        gap = outcome.gaps.get(name)
        out.print(
            f"  {name + f' [{lo:g}, {hi:g}]':<34} {shown:>18} "
            f"{'' if surrogate is None else f'{surrogate:.2f}':>10} {'' if gap is None else f'{gap:+.2f}':>8}"
        )


@app.command()
def solve(
    design_file: Annotated[
        Path, typer.Argument(help="Design with [appearance] targets and a [solve] table.")
    ],
    out_dir: Annotated[
        Path | None, typer.Option("--out", "-o", help="Output folder [default: NAME-solved].")
    ] = None,
    reachable: Annotated[
        bool,
        typer.Option("--reachable", help="Chart what the printer can reach within [solve]'s bounds instead."),
    ] = False,
    points: Annotated[int, typer.Option(min=8, max=100_000, help="--reachable: designs sampled.")] = 192,
    seed: Annotated[int | None, typer.Option(min=0, help="Optimiser seed [default: [solve] seed].")] = None,
    evaluations: Annotated[
        int | None,
        typer.Option(min=8, help="Surrogate evaluations per round [default: [solve] evaluations]."),
    ] = None,
    workers: WorkersOption = 2,
    scheduler: SchedulerOption = None,
    force: ForceOption = False,
    quiet: QuietOption = False,
) -> None:
    """Find the design whose predicted as-printed BRDF meets its [appearance] targets, and build it."""
    target = out_dir if out_dir is not None else Path(f"{design_file.stem}-solved")
    if reachable:
        from printapp.reachable import reachable_file

        with _bar("reachable set", quiet) as update:
            result = reachable_file(
                design_file, target, points=points, workers=workers, scheduler=scheduler, progress=update
            )
        out.print(result.summary)
        wrote(result.written)
        return
    from printapp.solve import solve_file

    with _status(quiet) as say:
        outcome, run, written = solve_file(
            design_file,
            target,
            workers=workers,
            scheduler=scheduler,
            seed=seed,
            evaluations=evaluations,
            force=force,
            quiet=True,
            progress=say,
        )
    counts = (
        f"{outcome.evaluations} surrogate evaluations and {outcome.traced} traced in {outcome.rounds} "
        f"round{'s' if outcome.rounds > 1 else ''} ({outcome.cache_hits} from the cache), "
        f"{outcome.seconds:.1f} s"
    )
    params = ", ".join(
        f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in outcome.params.items()
    )
    if not outcome.met:
        err.print(
            Text("error: ", style="bold red")
            + Text(f"no design within the bounds meets every target; the nearest ({params}):")
        )
        _targets_table(outcome)
        for reason in outcome.reasons:
            err.print(Text("missed: ", style="bold red") + Text(reason))
        for line in outcome.binding:
            err.print(Text("binds: ", style="bold yellow") + Text(line))
        out.print(counts)
        wrote(written)
        raise typer.Exit(3)
    out.print(f"solved: every target met ({counts})")
    out.print(f"parameters: {params}")
    _targets_table(outcome)
    if run is not None and run.render_warning:
        warn(run.render_warning)
    wrote(written)
    if run is not None and not run.passed:
        for reason in run.reasons:
            err.print(Text("verification failed: ", style="bold red") + Text(reason))
        raise typer.Exit(3)


@app.command()
def sweep(
    design_file: Annotated[Path, typer.Argument(help="Design file (TOML) whose variants to evaluate.")],
    vary: Annotated[
        list[str],
        typer.Option(
            "--vary", help="KEY=START:STOP:N or KEY=A,B,C, e.g. relief.amplitude_um=100:400:4 (repeat)."
        ),
    ],
    out_dir: Annotated[
        Path | None, typer.Option("--out", "-o", help="Output folder [default: NAME-sweep].")
    ] = None,
    until: Annotated[
        str, typer.Option("--until", help="How far: surrogate, brdf (traced) or design (everything).")
    ] = "design",
    lhs: Annotated[
        int | None, typer.Option("--lhs", min=1, help="N points of a Latin hypercube, not a grid.")
    ] = None,
    seed: Annotated[int, typer.Option(min=0, help="Seed of the Latin hypercube.")] = 0,
    workers: WorkersOption = 2,
    scheduler: SchedulerOption = None,
    quiet: QuietOption = False,
) -> None:
    """Evaluate variants of a design on Dask; write results.csv, results.parquet, timings.csv and charts."""
    from printapp.sweep import sweep_file

    target = out_dir if out_dir is not None else Path(f"{design_file.stem}-sweep")
    with _bar("sweep", quiet) as update:
        result = sweep_file(
            design_file,
            vary,
            target,
            until=until,
            lhs=lhs,
            seed=seed,
            workers=workers,
            scheduler=scheduler,
            progress=update,
        )
    passed = sum(1 for row in result.rows if row["verdict"] == "pass")
    out.print(
        f"sweep: {len(result.rows)} variants on {result.where}: {result.hits} from the cache, "
        f"{result.computed} computed, {result.seconds:.1f} s; {passed} pass"
    )
    wrote(result.written)
