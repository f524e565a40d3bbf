"""Monte Carlo campaigns: the one engine of ``ins-cosim verify`` and the reproductions.

A campaign runs one scenario ``runs`` times with seeds derived from one campaign seed
(:mod:`cosim.verify.seeds`), evaluates every requirement on every run (in the worker, on
the full recording) and judges each requirement over the runs
(:func:`cosim.verify.requirements.judge`). Where the runs go: :mod:`cosim.verify.workers`.

:func:`run_campaign` is ``ins-cosim verify``: requirements, report folder, resume.
:func:`simulate` runs the same jobs for a caller that analyses the full recordings itself
(the reproductions): per-run parameters (a reproduction's cases), other outputs, stop
time or recording interval, and the full columns in each :class:`RunRecord`.

On disk, under the report folder::

    campaign.json          what the campaign is (scenario hash, seed, runs, ...), for --resume
    runs/run_00042.json    one finished run: seeds, status, error, metrics per requirement
    runs/run_00042.npz     its decimated histories: time, e_<k> and s_<k> per requirement k
    metrics.csv            one row per run: status, seeds, metric and pass per requirement
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import ScenarioError
from cosim.foreign import foreign_fmus
from cosim.runs import assemble
from cosim.scenario import Scenario, load_scenario
from cosim.sensors.pairing import check_log_pairs, replay_blocks
from cosim.verify.dispatch import run_jobs
from cosim.verify.lock import holding_report_folder
from cosim.verify.pool import WorkerPool, keeps_workers
from cosim.verify.records import RunRecord, read_records, save_record, write_metrics_table
from cosim.verify.requirements import Requirement, Verdict
from cosim.verify.seeds import SEED_RULE, Stratified, run_seeds, stratified_draws
from cosim.verify.statistics import judge, overall_exit_code
from cosim.verify.tables import check_tables
from cosim.verify.workers import (
    CampaignError,
    Job,
    WorkerSpec,
    expand_parameters,
    share_scenario,
)

__all__ = [
    "Campaign",
    "CampaignError",
    "CampaignInterrupted",
    "CampaignSettings",
    "Prepared",
    "campaign_jobs",
    "parse_campaign",
    "prepare",
    "run_campaign",
    "simulate",
]

CAMPAIGN_KEYS = {"runs", "seed", "randomize", "stratify", "history_points", "on_failure"}
MANIFEST = "campaign.json"
RUNS_DIR = "runs"
METRICS_FILE = "metrics.csv"
REPORT_FILES = ("report.html", "junit.xml", "report.json")  # written by cosim.verify.report
FORMAT = "ins-cosim-campaign/1"


class CampaignInterrupted(Exception):  # noqa: N818 (an interruption, not an error)
    """The campaign was interrupted (Ctrl-C); finished runs are on disk.

    Parameters
    ----------
    done : int
        Runs finished and on disk.
    total : int
        Runs in the campaign.
    out_dir : Path
        The report folder (``--resume`` continues there).
    """

    def __init__(self, done: int, total: int, out_dir: Path) -> None:
        self.done, self.total, self.out_dir = done, total, out_dir
        super().__init__(
            f"interrupted: {done} of {total} runs are finished and kept in "
            f"{Path(out_dir) / RUNS_DIR}; continue with --resume"
        )


# --------------------------------------------------------------------------- settings
@dataclass
class CampaignSettings:
    """The ``[campaign]`` table.

    Attributes
    ----------
    runs : int
        Number of runs (default 1).
    seed : int
        Campaign seed (default 0), the entropy of the SeedSequence.
    randomize : tuple of str or None
        Blocks whose ``seed`` is drawn per run; None: every block with a seed parameter.
    stratify : tuple of str
        Parameters ``"block.name"`` the campaign draws itself, stratified over the runs
        (:mod:`cosim.verify.seeds`); empty: every block draws from its own seed.
    history_points : int
        At most this many samples of each run's error histories are kept (for plots).
    on_failure : str
        Default ``on_failure`` of the requirements (``"undecided"``, ``"exclude"``,
        ``"fail"``).
    strata : tuple of int
        Batch ends of the stratified design (``verify --until-decided``: its looks,
        :func:`cosim.verify.seeds.design_batches`); empty: one design over ``runs``.
    """

    runs: int = 1
    seed: int = 0
    randomize: tuple[str, ...] | None = None
    stratify: tuple[str, ...] = ()
    history_points: int = 500
    on_failure: str = "undecided"
    strata: tuple[int, ...] = ()

    @property
    def design(self) -> int | tuple[int, ...]:
        """The stratified design of the runs: ``strata``, else ``runs``."""
        return self.strata or self.runs


def parse_campaign(scenario: Scenario) -> CampaignSettings:
    """Read ``[campaign]`` of a scenario (all keys optional).

    Parameters
    ----------
    scenario : Scenario
        A loaded scenario.

    Returns
    -------
    CampaignSettings

    Raises
    ------
    ScenarioError
        Unknown key or bad value, naming the file and key.
    """
    table = scenario.raw.get("campaign", {})
    file = str(scenario.path)
    if not isinstance(table, dict):
        raise ScenarioError("expected a [campaign] table", file=file, key="campaign")
    for k in table:
        if k not in CAMPAIGN_KEYS:
            import difflib

            hint = difflib.get_close_matches(k, CAMPAIGN_KEYS, n=1)
            tip = f" Did you mean '{hint[0]}'?" if hint else ""
            raise ScenarioError(
                f"unknown key '{k}'.{tip} Allowed: {', '.join(sorted(CAMPAIGN_KEYS))}",
                file=file,
                key=f"campaign.{k}",
            )
    out = CampaignSettings()
    for key in ("runs", "seed", "history_points"):
        if key in table:
            value = table[key]
            low = 0 if key == "seed" else (2 if key == "history_points" else 1)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ScenarioError(
                    f"expected an integer >= {low}, got {value!r}", file=file, key=f"campaign.{key}"
                )
            setattr(out, key, value)
    if "randomize" in table:
        value = table["randomize"]
        if not isinstance(value, list) or not all(isinstance(b, str) for b in value):
            raise ScenarioError(
                "expected a list of block names, e.g. ['imu', 'flexure']",
                file=file,
                key="campaign.randomize",
            )
        out.randomize = tuple(value)
    if "stratify" in table:
        value = table["stratify"]
        if not isinstance(value, list) or not all(
            isinstance(p, str) and p.count(".") == 1 for p in value
        ):
            raise ScenarioError(
                "expected a list of 'block.parameter' names, e.g. ['imu.accel_bias']",
                file=file,
                key="campaign.stratify",
            )
        out.stratify = tuple(value)
    if "on_failure" in table:
        value = table["on_failure"]
        if value not in ("undecided", "exclude", "fail"):
            raise ScenarioError(
                f"expected 'undecided', 'exclude' or 'fail', got {value!r}",
                file=file,
                key="campaign.on_failure",
            )
        out.on_failure = value
    return out


# ------------------------------------------------------------------------- campaigns
@dataclass
class Campaign:
    """A finished campaign: runs, verdicts and provenance.

    Attributes
    ----------
    out_dir : Path
        The report folder.
    scenario : dict
        ``file``, ``name``, ``sha256``.
    settings : CampaignSettings
        Effective runs, seed, randomized blocks.
    requirements : list of Requirement
        In file order.
    records : list of RunRecord
        One per run, by index.
    verdicts : list of Verdict
        One per requirement.
    provenance : dict
        Blocks (kind, source, GUID, sha256), master settings, seeded blocks, seed rule,
        software versions.
    execution : dict
        Workers or cluster, runs done in this session, whether it was resumed.
    source : Scenario or None
        The scenario as parsed for the campaign (the error budget reads it, not the file).
    """

    out_dir: Path
    scenario: dict[str, Any]
    settings: CampaignSettings
    requirements: list[Requirement]
    records: list[RunRecord]
    verdicts: list[Verdict]
    provenance: dict[str, Any]
    execution: dict[str, Any]
    source: Scenario | None = field(default=None, repr=False, compare=False)

    @property
    def exit_code(self) -> int:
        """0 all satisfied, 1 any violated, 2 any undecided (and none violated)."""
        return overall_exit_code(self.verdicts)

    @property
    def failed_runs(self) -> list[RunRecord]:
        """Runs that stopped before their end."""
        return [r for r in self.records if r.failed]

    def metric_values(self, req: Requirement) -> np.ndarray:
        """Per-run metrics of a requirement.

        Parameters
        ----------
        req : Requirement
            One of :attr:`requirements`.

        Returns
        -------
        ndarray, shape (runs,)
            Metric per run in the requirement's metric unit; nan for failed or undecided
            runs.
        """
        out = np.full(len(self.records), math.nan)
        for i, rec in enumerate(self.records):
            m = rec.metrics.get(req.id)
            if m is not None:
                out[i] = m.value
        return out


@dataclass
class Prepared:
    """A checked scenario, ready for a campaign (see :func:`prepare`).

    Attributes
    ----------
    scenario : Scenario
        The loaded scenario.
    settings : CampaignSettings
        Its ``[campaign]`` table.
    requirements : list of Requirement
        Its ``[[requirements]]``, checked against the built system (empty when not
        asked for).
    seeded : list of str
        Blocks with a ``seed`` parameter that the campaign draws, in file order.
    metadata : dict
        Provenance (scenario hash, FMU hashes, versions) recorded with the campaign.
    stratified : tuple of Stratified
        The resolved ``[campaign] stratify`` parameters.
    parameters : dict
        The scenario's parameters after the build, ``{block: {name: SI value}}``.
    declared : dict
        Block -> names of its parameters (what a job may set).
    fmu_dir : str or None
        The FMU folder the scenario runs its built-in models from (absolute).
    replayed : tuple of str
        Blocks that replay a recorded log (every run reads the same samples).
    """

    scenario: Scenario
    settings: CampaignSettings
    requirements: list[Requirement]
    seeded: list[str]
    metadata: dict[str, Any]
    stratified: tuple[Stratified, ...] = ()
    parameters: dict[str, dict[str, Any]] | None = None
    declared: dict[str, set[str]] | None = None
    fmu_dir: str | None = None
    replayed: tuple[str, ...] = ()

    def check_parameters(self, parameters: Mapping[str, Mapping[str, Any]], what: str) -> None:
        """Refuse parameters of unknown blocks or names (before any run).

        Parameters
        ----------
        parameters : dict
            ``{block: {parameter: value or list}}`` of a job.
        what : str
            Where they come from, for the message (a case name).

        Raises
        ------
        CampaignError
            Naming the block or parameter.
        """
        declared = self.declared or {}
        for block, values in expand_parameters(parameters).items():
            if block not in declared:
                known = ", ".join(declared)
                raise CampaignError(f"{what}: unknown block '{block}' (blocks: {known})")
            for name in values:
                if name not in declared[block]:
                    raise CampaignError(f"{what}: block '{block}' has no parameter '{name}'")


def prepare(
    scenario: str | Path | Scenario,
    fmu_dir: str | Path | None = None,
    *,
    requirements: bool = True,
    outputs: Sequence[str] | None = None,
) -> Prepared:
    """Load a scenario, build it once to check it and collect units and provenance.

    The scenario is parsed here (unless given parsed) and built once; the runs made in
    this process use the same parse (:func:`cosim.verify.workers.share_scenario`).

    Parameters
    ----------
    scenario : str, Path or Scenario
        The scenario file, or the scenario as parsed (not changed).
    fmu_dir : str or Path, optional
        Run built-in models from these FMUs.
    requirements : bool
        Read and check ``[[requirements]]`` (a scenario without any is refused); False
        for a caller that analyses the recordings itself.
    outputs : sequence of str, optional
        What to record instead of the scenario's ``[output]``.

    Returns
    -------
    Prepared
        Scenario, campaign settings, requirements, seeded blocks, metadata.

    Raises
    ------
    ScenarioError, FmuError
        Bad scenario, requirement or campaign table.
    """
    fmu = None if fmu_dir is None else str(Path(fmu_dir).resolve())
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    settings = parse_campaign(sc)
    master = assemble(sc, fmu_dir=fmu, outputs=outputs).master
    share_scenario(sc)
    try:
        master.warn_loops()  # once here; the workers run silently
        check_log_pairs(sc, master)  # two logs in one run (cosim.sensors.pairing)
        checked = check_tables(sc, settings, master, requirements=requirements)
        replayed = tuple(replay_blocks(master))
    finally:
        master.terminate()
    return Prepared(
        sc,
        settings,
        checked.requirements,
        checked.seeded,
        master.metadata,
        checked.stratified,
        checked.parameters,
        checked.declared,
        fmu,
        replayed,
    )


def _manifest(prep: Prepared, runs: int, seed: int, fmu_dir: str | None) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "scenario": {
            "file": str(prep.scenario.path.resolve()),
            "name": prep.scenario.name,
            "sha256": prep.scenario.sha256,
        },
        "fmu_dir": fmu_dir,
        "runs": runs,
        "seed": seed,
        "seeded_blocks": prep.seeded,
        "randomize": list(prep.settings.randomize) if prep.settings.randomize is not None else None,
        "stratify": list(prep.settings.stratify),
        "history_points": prep.settings.history_points,
        "requirements": [r.id for r in prep.requirements],
    }


def _check_resume(old: dict[str, Any], new: dict[str, Any], out_dir: Path) -> None:
    def refuse(what: str) -> CampaignError:
        return CampaignError(
            f"{out_dir / MANIFEST}: cannot resume: {what}; run without --resume to start "
            f"over, or use another --report folder"
        )

    if old.get("format") != FORMAT:
        raise refuse("not a campaign written by this version of ins-cosim")
    if old["scenario"]["sha256"] != new["scenario"]["sha256"]:
        raise refuse(
            f"the scenario file changed since the campaign started (sha256 "
            f"{old['scenario']['sha256'][:12]} -> {new['scenario']['sha256'][:12]})"
        )
    keys = ("seed", "fmu_dir", "seeded_blocks", "randomize", "stratify", "strata")
    for key in (*keys, "history_points"):
        if old.get(key, []) != new.get(key, []):
            raise refuse(f"{key} was {old.get(key)!r}, now {new.get(key)!r}")
    if new["runs"] < old["runs"]:
        raise refuse(f"it has {old['runs']} runs; --runs can add runs, not remove them")
    if new["runs"] != old["runs"] and new.get("stratify") and not new.get("strata"):
        raise refuse(
            f"its draws are stratified over {old['runs']} runs; --runs cannot change the design"
        )


@holding_report_folder("out_dir")  # one campaign at a time in a report folder
@keeps_workers  # a pool made now: its forkserver imports while prepare() checks
def run_campaign(
    scenario: str | Path | Scenario | Prepared,
    out_dir: str | Path,
    *,
    runs: int | None = None,
    seed: int | None = None,
    workers: int | None = None,
    cluster: str | None = None,
    fmu_dir: str | Path | None = None,
    resume: bool = False,
    progress: bool = True,
    only_runs: Sequence[int] | None = None,
    rerun_crashed: bool = False,
    strata: Sequence[int] | None = None,
    pool: WorkerPool | None = None,
) -> Campaign:
    """Run (or resume) a Monte Carlo campaign and judge its requirements.

    Parameters
    ----------
    scenario : str, Path, Scenario or Prepared
        Scenario file with ``[[requirements]]`` (and optionally ``[campaign]``), parsed
        or not, or already prepared (:func:`prepare` with this ``fmu_dir``: the looks of
        ``--until-decided``); parsed once in this process.
    out_dir : str or Path
        Report folder: ``campaign.json``, ``runs/``, ``metrics.csv``.
    runs, seed : int, optional
        Override ``[campaign] runs`` and ``seed``.
    workers : int, optional
        Local worker processes (default: the number of CPUs; 1 runs in this process).
    cluster : str, optional
        Address of a Dask scheduler (``tcp://host:8786``); replaces local workers.
    fmu_dir : str or Path, optional
        Run built-in models from the FMUs in this folder.
    resume : bool
        Keep the finished runs in ``out_dir`` and run the rest. Without it, runs left
        in ``out_dir`` by an earlier campaign are deleted first.
    progress : bool
        Show a progress bar with ETA on stderr.
    only_runs : sequence of int, optional
        Run (and judge) only these runs of the campaign of ``runs`` runs: each has the
        seeds and stratified draws it has in the whole campaign.
    rerun_crashed : bool
        With ``resume``: run again the runs recorded as crashed (their worker died).
    strata : sequence of int, optional
        Batch ends of the stratified design (the looks of ``verify --until-decided``,
        each batch its own Latin hypercube); ``runs`` may grow up to the last. Default:
        one design over ``runs``. Ignored without ``[campaign] stratify``.
    pool : cosim.verify.pool.WorkerPool, optional
        Run on these worker processes (they stay for the caller's next campaign, e.g.
        the next look of ``--until-decided``); replaces ``workers``.

    Returns
    -------
    Campaign

    Raises
    ------
    ScenarioError, FmuError, CampaignError
        Bad input (before any run).
    CampaignInterrupted
        On Ctrl-C; the finished runs are on disk.
    """
    prep = scenario if isinstance(scenario, Prepared) else prepare(scenario, fmu_dir)
    fmu = prep.fmu_dir
    settings = dataclasses.replace(prep.settings)  # this campaign's runs, seed, strata
    if runs is not None:
        if runs < 1:
            raise CampaignError(f"--runs must be >= 1, got {runs}")
        settings.runs = runs
    if seed is not None:
        if seed < 0:
            raise CampaignError(f"--seed must be >= 0, got {seed}")
        settings.seed = seed
    if workers is None:
        workers = os.cpu_count() or 1
    if workers < 1:
        raise CampaignError(f"--workers must be >= 1, got {workers}")
    if strata and prep.stratified:
        settings.strata = tuple(strata)
        if settings.runs > strata[-1]:
            raise CampaignError(f"{settings.runs} runs exceed the stratified design {strata}")
    if only_runs is not None:
        if resume:
            raise CampaignError("--only-run and --resume cannot be combined")
        bad = [i for i in only_runs if not 0 <= i < settings.runs]
        if bad:
            raise CampaignError(
                f"--only-run {bad[0]}: the campaign has runs 0 to {settings.runs - 1}"
            )

    out = Path(out_dir)
    runs_dir = out / RUNS_DIR
    manifest = _manifest(prep, settings.runs, settings.seed, fmu)
    if settings.strata:
        manifest["strata"] = list(settings.strata)
    if only_runs is not None:
        manifest["only_runs"] = sorted(set(only_runs))
    manifest_file = out / MANIFEST
    if resume:
        if not manifest_file.is_file():
            raise CampaignError(f"{out}: no campaign to resume (no {MANIFEST}); drop --resume")
        old = json.loads(manifest_file.read_text())
        if "only_runs" in old:
            raise CampaignError(f"{out}: a campaign of --only-run runs cannot be resumed")
        if runs is None:
            manifest["runs"] = settings.runs = int(old["runs"])
        _check_resume(old, manifest, out)
    else:
        stale = [out / name for name in (METRICS_FILE, *REPORT_FILES)]
        for f in (*runs_dir.glob("run_*"), *runs_dir.glob(".run_*"), *stale):
            f.unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    from cosim.verify.records import write_atomic  # readers never see half a manifest

    write_atomic(manifest_file, json.dumps(manifest, indent=2) + "\n")
    for tmp in runs_dir.glob(".run_*.tmp"):
        tmp.unlink()

    finished = read_records(runs_dir, settings.runs, crashed=not rerun_crashed) if resume else {}
    wanted = sorted(set(only_runs)) if only_runs is not None else list(range(settings.runs))
    todo = [i for i in wanted if i not in finished]
    jobs = campaign_jobs(prep, settings.seed, settings.runs, indices=todo, strata=settings.strata)
    randomized = prep.seeded if settings.randomize is None else list(settings.randomize)
    spec = WorkerSpec(
        scenario=str(prep.scenario.path.resolve()),
        sha256=prep.scenario.sha256,
        fmu_dir=fmu,
        requirements=tuple(prep.requirements),
        history_points=settings.history_points,
        isolate=bool(foreign_fmus(prep.scenario, fmu)),
    )

    bar = _progress(len(wanted), len(finished), progress)
    count = [len(finished)]

    saved: dict[int, RunRecord] = dict(finished)

    def done(record: RunRecord) -> None:
        saved[record.index] = save_record(record, runs_dir)  # judged from this, not re-read
        count[0] += 1
        bar.update(1)
        if record.failed:
            bar.write(f"run {record.index} failed: {record.error}", file=sys.stderr)

    try:
        run_jobs(spec, jobs, done, workers=workers, cluster=cluster, pool=pool)
    except KeyboardInterrupt:
        raise CampaignInterrupted(count[0], len(wanted), out) from None
    finally:
        bar.close()

    missing = [i for i in wanted if i not in saved]
    if missing:  # a run handed back by no worker: a bug, not a user's mistake
        raise CampaignError(f"runs {missing[:5]} were not run")
    records = [saved[i] for i in wanted]
    verdicts = [
        judge(req, [r.metrics.get(req.id) for r in records], replayed=prep.replayed)
        for req in prep.requirements
    ]
    meta = prep.metadata
    blocks_seeds = {b: meta["seeds"].get(b) for b in prep.seeded}
    master = prep.scenario.settings
    campaign = Campaign(
        out_dir=out,
        scenario=manifest["scenario"],
        settings=settings,
        requirements=prep.requirements,
        records=records,
        verdicts=verdicts,
        provenance={
            "blocks": meta["blocks"],
            "master": {
                "step": master.step,
                "start": master.start,
                "stop": master.stop,
                "coupling": master.coupling,
                "record_every": master.record_every,
            },
            "seeded_blocks": prep.seeded,
            "randomized_blocks": randomized,
            "replayed_blocks": list(prep.replayed),
            "stratified": list(settings.stratify),
            "file_seeds": blocks_seeds,
            "seed_rule": SEED_RULE,
            "units": meta["units"],
            "software": software_versions(),
        },
        execution={
            "workers": None if cluster else (pool.workers if pool is not None else workers),
            "cluster": cluster,
            "resumed": resume,
            "runs_this_session": len(jobs),
            "only_runs": manifest.get("only_runs"),
            "fmu_dir": fmu,
        },
        source=prep.scenario,
    )
    write_metrics_table(campaign, out / METRICS_FILE)
    return campaign


def campaign_jobs(
    prep: Prepared,
    seed: int,
    runs: int,
    *,
    indices: Iterable[int] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    stratify: bool = True,
    tag: str = "",
    strata: Sequence[int] = (),
) -> list[Job]:
    """The jobs of a campaign: each run's seeds and stratified draws, and parameters.

    Parameters
    ----------
    prep : Prepared
        The scenario (:func:`prepare`).
    seed : int
        Campaign seed.
    runs : int
        Runs of the campaign (the stratified design's size).
    indices : iterable of int, optional
        The runs to make jobs for (default ``0 .. runs - 1``).
    parameters : dict, optional
        ``{block: {parameter: SI value or list}}`` for every job (checked).
    stratify : bool
        Draw the ``[campaign] stratify`` parameters from the design; False: the blocks
        draw them from their seeds.
    tag : str
        Label of the jobs (copied into each record).
    strata : sequence of int
        Batch ends of the stratified design (:func:`cosim.verify.seeds.design_batches`);
        empty: one design over ``runs``.

    Returns
    -------
    list of Job

    Raises
    ------
    CampaignError
        An unknown block or parameter, or an index outside the campaign.
    """
    params = {b: dict(v) for b, v in (parameters or {}).items()}
    if params:
        prep.check_parameters(params, tag or "parameters")
    randomized = prep.seeded if prep.settings.randomize is None else prep.settings.randomize
    out = []
    for i in range(runs) if indices is None else indices:
        if not 0 <= i < runs:
            raise CampaignError(f"{tag or 'campaign'}: run {i} is outside 0 .. {runs - 1}")
        seeds = {b: s for b, s in run_seeds(seed, i, prep.seeded).items() if b in randomized}
        draws = stratified_draws(prep.stratified, strata or runs, seed, i) if stratify else ()
        out.append(Job(int(i), seeds, params, draws, tag))
    return out


def simulate(
    prep: Prepared,
    jobs: Sequence[Job],
    *,
    outputs: Sequence[str] | None = None,
    stop: float | None = None,
    record_every: int | None = None,
    workers: int = 1,
    cluster: str | None = None,
) -> list[RunRecord]:
    """Run jobs of a prepared scenario and return their records with the full columns.

    The same workers as :func:`run_campaign` (built once per worker, reset between runs);
    no report folder, no requirements.

    Parameters
    ----------
    prep : Prepared
        The scenario (:func:`prepare`, with ``requirements=False`` if it has none).
    jobs : sequence of Job
        From :func:`campaign_jobs` (or made by the caller with the same seed rule).
    outputs : sequence of str, optional
        What to record (``output.variables`` syntax), instead of the scenario's.
    stop : float, optional
        Stop time [s] instead of the scenario's.
    record_every : int, optional
        Record every k-th macro step instead of the scenario's interval.
    workers : int
        Local processes (1: this process).
    cluster : str, optional
        Address of a Dask scheduler.

    Returns
    -------
    list of RunRecord
        In the order of ``jobs``, each with :attr:`RunRecord.columns` and
        :attr:`RunRecord.parameters`.
    """
    spec = WorkerSpec(
        scenario=str(prep.scenario.path.resolve()),
        sha256=prep.scenario.sha256,
        fmu_dir=prep.fmu_dir,
        history_points=2,
        stop=None if stop is None else float(stop),
        record_every=None if record_every is None else int(record_every),
        outputs=None if outputs is None else tuple(outputs),
        keep=True,
    )
    finished: list[RunRecord] = []
    run_jobs(spec, jobs, finished.append, workers=workers, cluster=cluster)
    keyed = {(r.tag, r.index): r for r in finished}
    return [keyed[(j.tag, j.index)] for j in jobs]


def _progress(total: int, initial: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit="run",
        desc="runs",
        file=sys.stderr,
        disable=not enabled,
        dynamic_ncols=True,
    )


def software_versions() -> dict[str, str]:
    """Versions of Python, ins-cosim and every package a campaign and its report use.

    Returns
    -------
    dict
        Package -> version (missing packages are left out).
    """
    from cosim import provenance

    return provenance.versions(("dask", "distributed", "matplotlib", "tqdm", "click"))
