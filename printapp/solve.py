"""``printapp solve``: the design whose predicted as-printed appearance meets its ``[appearance]`` targets.

Analysis by synthesis, in rounds (DESIGN.md, "inverse problems"):

1. **Search on the surrogate.** The free parameters of ``[solve]`` span the space; each
   candidate is built, sliced and cured as ``printapp design`` would make it, and the
   glossmeter on its facets (:mod:`render.facets`) predicts its gloss, haze and highlight in
   about a second. Optuna's TPE sampler (seeded: the same design and seed give the same
   search) proposes candidates in batches of :data:`BATCH`, evaluated in parallel through
   the engine that ``printapp sweep`` uses (:class:`printapp.engine.Engine`, cached), and
   minimises the squared distance of the predictions from the targets (each measured in
   units of :data:`SCALES`; the targets shrunk by a safety margin). A round stops when
   enough candidates meet the targets, when its best has not improved for :data:`PATIENCE`
   batches, or after ``[solve] evaluations``.
2. **Confirm with the truth.** The best ``[solve] confirm`` candidates are traced
   (:func:`printapp.rendering.predict_for_design`: the BRDF ``printapp design`` reports).
   One that meets every target with the traced values is the answer.
3. **Correct by the gap.** Otherwise the gap between the tracer and the surrogate at the best
   candidate is taken off the targets the surrogate is asked to meet, every earlier
   evaluation is scored again against them (no new work: they are cached), and the next
   round searches from there; a round that brings the traced values no nearer is the last.

When no round finds a design, the nearest one (by the traced values) is reported with what
binds it: a bound of ``[solve]`` (relaxing it helps, as a probe beyond it shows), the
printer's layer height (a probe at its thinnest layers helps), its pixel pitch (features
already at two pixels), or the resin's refractive index (a flat mirror of it is less glossy
than the target).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from printapp.design import Design, TileBase
from printapp.errors import DesignError

BATCH = 8
"""Candidates asked of the optimiser at once (fixed, so that the search does not depend on the workers)."""
SCALES = {
    "gloss_20": 2.0,
    "gloss_60": 2.0,
    "gloss_85": 2.0,
    "haze": 2.0,
    "highlight_azimuth_deg": 2.0,
    "anisotropy": 0.05,
    "roughness": 0.05,
}
"""One unit of miss per target (GU, degrees; for anisotropy and roughness, of their logarithm)."""
LOG_TARGETS = ("anisotropy", "roughness")
PATIENCE = 4
"""Batches without a 1 % better candidate after which a round stops (once it has had twice that many)."""
MARGIN = 0.25
"""The share of a target's half-width (at most its scale) the surrogate is asked to stay inside it by."""
PARAMETERS = {
    "amplitude_um": ("relief.amplitude_um", "log"),
    "feature_size_mm": ("texture.feature_size_mm", "log"),
    "stretch": ("texture.stretch", "log"),
    "angle_deg": ("texture.angle_deg", "linear"),
    "octaves": ("texture.octaves", "int"),
    "pixel_texture_um": ("relief.pixel_texture_um", "linear"),
    "kind": ("texture.kind", "choice"),
    "grey_levels": ("relief.grey_levels", "choice"),
}
"""Each ``[solve]`` key: the design key it sets and how it is searched."""


def targets_of(design: Design) -> dict[str, tuple[float, float]]:
    """The design's ``[appearance]`` targets as ``{name: (min, max)}``."""
    from printapp.evaluate import TARGETS

    return {name: getattr(design.appearance, name) for name in TARGETS if getattr(design.appearance, name)}


def value_of(name: str, metrics: dict[str, float], traced: bool) -> float:
    """The metric a target is checked against: traced where asked and available, else the surrogate's."""
    from printapp.evaluate import SLOPE_TARGETS

    if traced and name not in SLOPE_TARGETS and metrics.get(name) is not None:
        return metrics[name]
    return metrics[f"surrogate_{name}"]


def miss(name: str, value: float, target: tuple[float, float]) -> float:
    """How far ``value`` lies outside ``target``, in units of :data:`SCALES` (0 inside)."""
    lo, hi = target
    if name == "highlight_azimuth_deg":
        if lo <= value <= hi:
            return 0.0
        gap = min(min(abs(value - b), 180.0 - abs(value - b)) for b in (lo, hi))
        return gap / SCALES[name]
    if name in LOG_TARGETS:
        value, lo, hi = (math.log(max(v, 1e-9)) for v in (value, lo, hi))
    return max(lo - value, 0.0, value - hi) / SCALES[name]


def shrunk(name: str, target: tuple[float, float], shift: float = 0.0) -> tuple[float, float]:
    """The target moved by ``shift`` (the surrogate's expected error) and shrunk by the margin."""
    from printapp.design_solve import TARGET_LIMITS

    if name in LOG_TARGETS:
        return target  # anisotropy and roughness are the slopes' own: no gap, no margin needed
    limit_lo, limit_hi = TARGET_LIMITS[name]
    margin = min(MARGIN * 0.5 * (target[1] - target[0]), SCALES[name])
    # A one-sided target (its other end at the measure's limit) is not shrunk at that end.
    lo = target[0] if target[0] <= limit_lo else target[0] + margin
    hi = target[1] if target[1] >= limit_hi else target[1] - margin
    return lo - shift, hi - shift


def loss(metrics: dict[str, float], goals: dict[str, tuple[float, float]]) -> float:
    """Sum of squared misses of the surrogate's predictions from ``goals``."""
    if not metrics:
        return 1e6  # refused (e.g. over the memory budget)
    return sum(miss(n, value_of(n, metrics, False), t) ** 2 for n, t in goals.items())


@dataclass
class Candidate:
    """A point of the search: its parameters, design and surrogate (and, once confirmed, traced) result."""

    params: dict[str, Any]
    design: Design
    result: dict[str, Any]
    traced: dict[str, Any] | None = None


@dataclass
class SolveOutcome:
    """What ``printapp solve`` found: the design (or the nearest), the values, the counts, what binds."""

    met: bool
    design: Design
    params: dict[str, Any]
    targets: dict[str, tuple[float, float]]
    achieved: dict[str, float]
    surrogate: dict[str, float]
    gaps: dict[str, float]
    evaluations: int
    traced: int
    cache_hits: int
    rounds: int
    seconds: float
    binding: list[str] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)

    def record(self) -> dict[str, Any]:
        """The solve's account for ``solve.json`` (the seconds in it differ between runs)."""
        return {
            "met": self.met,
            "params": self.params,
            "targets": {k: list(v) for k, v in self.targets.items()},
            "achieved_traced": self.achieved,
            "surrogate": self.surrogate,
            "gap_traced_minus_surrogate": self.gaps,
            "surrogate_evaluations": self.evaluations,
            "traced_evaluations": self.traced,
            "cache_hits": self.cache_hits,
            "rounds": self.rounds,
            "seconds": round(self.seconds, 2),
            "binding": self.binding,
            "reasons": self.reasons,
            "optimiser": "optuna TPE (seeded), batches of 8, surrogate targets corrected by the traced gap",
        }


class Space:
    """The free parameters of ``[solve]`` as optuna distributions, and candidates from their values."""

    def __init__(self, design: Design) -> None:
        import optuna

        from printapp.sweep import design_raw

        solve = design.solve
        if solve is None:
            raise DesignError("the design has no [solve] table; expected one naming the free parameters")
        self.design = design
        self.raw = design_raw(design)
        self.fixed: dict[str, Any] = {}
        self.distributions: dict[str, Any] = {}
        for name, (_, how) in PARAMETERS.items():
            given = getattr(solve, name)
            if given is None:
                continue
            if how == "choice":
                choices = list(given)
                if len(choices) == 1:
                    self.fixed[name] = choices[0]
                else:
                    self.distributions[name] = optuna.distributions.CategoricalDistribution(choices)
            elif given[0] == given[1]:
                self.fixed[name] = int(given[0]) if how == "int" else float(given[0])
            elif how == "int":
                self.distributions[name] = optuna.distributions.IntDistribution(int(given[0]), int(given[1]))
            else:
                self.distributions[name] = optuna.distributions.FloatDistribution(
                    float(given[0]), float(given[1]), log=how == "log"
                )
        if not self.distributions:
            raise DesignError("[solve] leaves nothing free; expected at least one parameter with a range")

    def start(self) -> dict[str, Any]:
        """The design's own values of the free parameters, moved inside their bounds."""
        current = {
            "amplitude_um": self.design.relief.amplitude_mm * 1000.0,
            "feature_size_mm": self.design.texture.feature_size_mm,
            "stretch": self.design.texture.stretch,
            "angle_deg": math.degrees(self.design.texture.angle_rad),
            "octaves": self.design.texture.octaves,
            "pixel_texture_um": self.design.relief.pixel_texture_mm * 1000.0,
            "kind": self.design.texture.kind,
            "grey_levels": self.design.relief.grey_levels,
        }
        out = {}
        for name, dist in self.distributions.items():
            value = current[name]
            if hasattr(dist, "choices"):
                out[name] = value if value in dist.choices else dist.choices[0]
            else:
                out[name] = min(max(value, dist.low), dist.high)
        return out

    def candidate(self, params: dict[str, Any], **overrides: Any) -> Design:
        """The design with ``params`` (and the fixed values) set; ``overrides`` are design keys."""
        from printapp.sweep import with_values

        values = {PARAMETERS[n][0]: v for n, v in {**self.fixed, **params}.items()}
        values.update(overrides)
        return with_values(self.raw, values, "[solve]")


def _round_params(params: dict[str, Any]) -> dict[str, Any]:
    return {k: round(v, 6) if isinstance(v, float) else v for k, v in params.items()}


def solve_design(
    design: Design,
    engine: Any,
    *,
    progress: Callable[[str], None] | None = None,
) -> SolveOutcome:
    """Search, confirm and correct (see the module) until the targets are met or the rounds run out."""
    import optuna
    from optuna.samplers import TPESampler

    from printapp.engine import Job
    from printapp.evaluate import target_misses

    if not isinstance(design.base, TileBase) or design.combine:
        raise DesignError("solve needs a tile without booleans: it predicts the as-printed relief of tiles")
    targets = targets_of(design)
    if not targets:
        raise DesignError("the design has no [appearance] targets; expected at least one to solve for")
    assert design.solve is not None
    space = Space(design)
    solve = design.solve
    say = progress or (lambda _: None)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    start = time.perf_counter()
    history: list[Candidate] = []
    confirmed: list[Candidate] = []
    shifts = dict.fromkeys(targets, 0.0)
    evaluations = traced_count = 0
    rounds = 0
    nearest_before = math.inf

    def evaluate(designs: list[Design], level: str) -> list[dict[str, Any]]:
        from printapp.design_io import resolved_toml

        return [o.result for o in engine.run([Job(resolved_toml(d), level) for d in designs])]

    for round_ in range(solve.rounds):
        rounds = round_ + 1
        goals = {n: shrunk(n, t, shifts[n]) for n, t in targets.items()}
        study = optuna.create_study(
            direction="minimize",
            sampler=TPESampler(seed=solve.seed + round_, n_startup_trials=2 * BATCH, multivariate=True),
        )
        for c in history:  # earlier evaluations, scored against this round's goals
            study.add_trial(
                optuna.trial.create_trial(
                    params=c.params, distributions=space.distributions, value=loss(c.result["metrics"], goals)
                )
            )
        if not history:
            study.enqueue_trial(space.start())
        done = 0
        best_seen, stale = math.inf, 0
        while done < solve.evaluations:
            trials = [study.ask(space.distributions) for _ in range(min(BATCH, solve.evaluations - done))]
            batch = [Candidate(t.params, space.candidate(t.params), {}) for t in trials]
            for c, result in zip(batch, evaluate([c.design for c in batch], "surrogate"), strict=True):
                c.result = result
            for t, c in zip(trials, batch, strict=True):
                study.tell(t, loss(c.result["metrics"], goals))
            history += batch
            done += len(batch)
            evaluations += len(batch)
            good = sum(1 for c in history if loss(c.result["metrics"], goals) == 0.0)
            say(f"round {rounds}: {done} candidates on the surrogate, {good} meet the targets")
            if good >= solve.confirm:
                break
            # Patience: a search whose best has not moved for PATIENCE batches has converged.
            lowest = min(loss(c.result["metrics"], goals) for c in batch)
            if lowest < best_seen * 0.99 - 1e-9:
                best_seen, stale = lowest, 0
            else:
                stale += 1
                if stale >= PATIENCE and done >= 2 * BATCH * PATIENCE:
                    break
        ranked = sorted(
            (c for c in history if c.traced is None), key=lambda c: loss(c.result["metrics"], goals)
        )[: solve.confirm]
        for c, result in zip(ranked, evaluate([c.design for c in ranked], "brdf"), strict=True):
            c.traced = result
            confirmed.append(c)
        traced_count += len(ranked)
        passing = [c for c in confirmed if c.traced and c.traced["verdict"] == "pass"]
        say(f"round {rounds}: traced {len(ranked)}, {len(passing)} meet every target")
        if passing:
            best = min(passing, key=lambda c: _centredness(c.traced["metrics"], targets))
            return _outcome(True, best, targets, space, evaluations, traced_count, engine, rounds, start)
        best = min(confirmed, key=lambda c: _traced_loss(c, targets))
        nearest = _traced_loss(best, targets)
        if nearest > 0.99 * nearest_before - 1e-9:
            break  # a round that brought the truth no nearer: another will not either
        nearest_before = nearest
        for n in targets:
            shifts[n] = value_of(n, best.traced["metrics"], True) - value_of(n, best.result["metrics"], False)
    best = min(confirmed, key=lambda c: _traced_loss(c, targets))
    outcome = _outcome(False, best, targets, space, evaluations, traced_count, engine, rounds, start)
    outcome.reasons = target_misses(best.design, best.traced["metrics"]) or list(best.traced["reasons"])
    outcome.binding = binding_limits(best, space, targets, shifts, evaluate)
    outcome.seconds = time.perf_counter() - start
    return outcome


def _traced_loss(c: Candidate, targets: dict[str, tuple[float, float]]) -> float:
    assert c.traced is not None
    if not c.traced["metrics"]:
        return 1e6
    return sum(miss(n, value_of(n, c.traced["metrics"], True), t) ** 2 for n, t in targets.items())


def _centredness(metrics: dict[str, float], targets: dict[str, tuple[float, float]]) -> float:
    """Minus how deep inside their targets the traced values sit (each depth in units of its scale, at
    most 3): the passing design chosen is the one with the most room."""
    total = 0.0
    for n, (lo, hi) in targets.items():
        value = value_of(n, metrics, True)
        if n in LOG_TARGETS:
            value, lo, hi = (math.log(max(v, 1e-9)) for v in (value, lo, hi))
        total += min(min(value - lo, hi - value) / SCALES[n], 3.0)
    return -total


def _outcome(
    met: bool,
    best: Candidate,
    targets: dict[str, tuple[float, float]],
    space: Space,
    evaluations: int,
    traced: int,
    engine: Any,
    rounds: int,
    start: float,
) -> SolveOutcome:
    assert best.traced is not None
    metrics = best.traced["metrics"]
    achieved = {n: round(value_of(n, metrics, True), 3) for n in targets} if metrics else {}
    surrogate = {n: round(value_of(n, best.result["metrics"], False), 3) for n in targets} if metrics else {}
    gaps = {n: round(achieved[n] - surrogate[n], 3) for n in achieved}
    return SolveOutcome(
        met,
        best.design,
        _round_params({**space.fixed, **best.params}),
        targets,
        achieved,
        surrogate,
        gaps,
        evaluations,
        traced,
        engine.hits,
        rounds,
        time.perf_counter() - start,
    )


def flat_gloss(design: Design) -> dict[str, float]:
    """The gloss (GU) of a mirror-flat surface of the design's resin: no relief is glossier."""
    import numpy as np

    from noise.heightfield import HeightField
    from printapp.brdf import grey_albedo
    from printapp.material_design import derive_design_material
    from render.facets import facet_appearance

    resolved, _ = derive_design_material(design)
    flat = facet_appearance(
        HeightField(np.zeros((8, 8)), 0.05, 0.05),
        ior=resolved.material.refractive_index,
        body_albedo=grey_albedo(resolved.material.body_albedo),
    )
    return {k: flat[k] for k in ("gloss_20", "gloss_60", "gloss_85")}


def binding_limits(
    best: Candidate,
    space: Space,
    targets: dict[str, tuple[float, float]],
    shifts: dict[str, float],
    evaluate: Callable[[list[Design], str], list[dict[str, Any]]],
) -> list[str]:
    """What keeps the nearest design from the targets, each as one sentence (see the module)."""
    lines = []
    goals = {n: shrunk(n, t, shifts[n]) for n, t in targets.items()}
    here = loss(best.result["metrics"], goals)
    ceiling = flat_gloss(best.design)
    for name in ("gloss_20", "gloss_60", "gloss_85"):
        if name in targets and targets[name][0] > ceiling[name]:
            lines.append(
                f"the resin's refractive index ({best.design.material.refractive_index:g}): a mirror-flat "
                f"surface of it reaches {ceiling[name]:.1f} GU at {name[6:]} degrees, below the target's "
                f"{targets[name][0]:g}"
            )
    probes: list[tuple[str, Design]] = []
    for name, dist in space.distributions.items():
        value = best.params[name]
        if hasattr(dist, "choices"):
            continue
        span = dist.high - dist.low
        for bound, outward in ((dist.low, -1.0), (dist.high, 1.0)):
            if abs(value - bound) > 0.02 * span:
                continue
            if PARAMETERS[name][1] == "log":
                beyond = bound * (1.5 if outward > 0 else 1 / 1.5)
            elif PARAMETERS[name][1] == "int":
                beyond = bound + int(outward)
            else:
                beyond = bound + outward * max(0.5 * span, 1.0)
            try:
                probe = space.candidate({**best.params, name: beyond})
            except DesignError:
                continue
            side = "upper" if outward > 0 else "lower"
            probes.append(
                (f"bounds: solve.{name} at its {side} bound {bound:g} ({name} {beyond:g} beyond it", probe)
            )
    profile = best.design.printer.profile
    if best.design.layer_height_mm > profile.min_layer_height_mm:
        thin = space.candidate(best.params, **{"printer.layer_height_mm": profile.min_layer_height_mm})
        probes.append(
            (f"layer height: {best.design.layer_height_mm:g} mm (at {profile.min_layer_height_mm:g} mm", thin)
        )
    results = evaluate([p for _, p in probes], "surrogate") if probes else []
    for (text, _), result in zip(probes, results, strict=True):
        after = loss(result["metrics"], goals)
        if after < here * 0.9 - 1e-9:
            shown = ", ".join(f"{n} {value_of(n, result['metrics'], False) + shifts[n]:.1f}" for n in targets)
            lines.append(f"{text} would reach {shown})")
    pitch = profile.pitch_mm
    feature = best.design.texture.feature_size_mm
    if "feature_size_mm" in space.distributions and feature <= 2.05 * pitch:
        lines.append(
            f"pixel pitch: features are already {feature:.3g} mm, two {pitch:.4g} mm pixels, "
            "the finest the printer makes"
        )
    if not lines:
        lines.append("no single limit: the targets pull against each other within these bounds")
    return lines


def write_solved(
    outcome: SolveOutcome, out_dir: Path, *, source: str, force: bool = False, quiet: bool = False
) -> tuple[Any, list[Path]]:
    """Write ``design.solved.toml``, ``solve.json`` and (when met) everything ``printapp design`` writes.

    When the targets were not met, ``design.nearest.toml`` and ``solve.json`` only. Returns the
    design run's outcome (None when none ran) and the files written.
    """
    import json

    from printapp.design_io import resolved_toml
    from printapp.outputs import atomic_write_files

    record = json.dumps(outcome.record(), indent=2, sort_keys=True) + "\n"
    if not outcome.met:
        out_dir.mkdir(parents=True, exist_ok=True)
        files = [
            (out_dir / "design.nearest.toml", resolved_toml(outcome.design).encode()),
            (out_dir / "solve.json", record.encode()),
        ]
        return None, atomic_write_files(files)
    from printapp.pipeline import run_design

    run = run_design(outcome.design, out_dir, source=f"{source} (solved)", force=force, quiet=quiet)
    extra = atomic_write_files(
        [
            (out_dir / "design.solved.toml", resolved_toml(outcome.design).encode()),
            (out_dir / "solve.json", record.encode()),
        ]
    )
    return run, extra + run.written


def check_solvable(design: Design) -> None:
    """Refuse, before any work, a design ``printapp solve`` cannot solve (exit 2, naming what is missing)."""
    if design.solve is None:
        raise DesignError(
            "the design has no [solve] table; expected one naming the free parameters and bounds"
        )
    if not targets_of(design):
        raise DesignError("the design has no [appearance] targets; expected at least one to solve for")
    Space(design)


def solve_file(
    path: Path,
    out_dir: Path,
    *,
    workers: int = 2,
    scheduler: str | None = None,
    seed: int | None = None,
    evaluations: int | None = None,
    force: bool = False,
    quiet: bool = False,
    progress: Callable[[str], None] | None = None,
) -> tuple[SolveOutcome, Any, list[Path]]:
    """``printapp solve``: load, check, solve on the engine (cache in ``out_dir/cache``), write.

    Returns the solve's outcome, the ``printapp design`` run of the solved design (None when
    the targets were not met) and the files written.
    """
    from printapp.design_io import load_design
    from printapp.engine import Engine

    design = _with_solve_options(load_design(path), seed, evaluations)
    check_solvable(design)
    if out_dir.exists() and not out_dir.is_dir():
        raise DesignError(f"{out_dir}: output folder is a file, expected a folder")
    with Engine(out_dir / "cache", workers=workers, scheduler=scheduler) as engine:
        outcome = solve_design(design, engine, progress=progress)
    run, written = write_solved(outcome, out_dir, source=str(path), force=force, quiet=quiet)
    return outcome, run, written


def _with_solve_options(design: Design, seed: int | None, evaluations: int | None) -> Design:
    if design.solve is None or (seed is None and evaluations is None):
        return design
    updates: dict[str, int] = {}
    if seed is not None:
        updates["seed"] = seed
    if evaluations is not None:
        updates["evaluations"] = evaluations
    from printapp.design_solve import Solve

    try:
        solve = Solve.model_validate({**design.solve.model_dump(), **updates})
    except ValueError as exc:
        raise DesignError(f"--seed/--evaluations: {exc}") from None
    return design.model_copy(update={"solve": solve})
