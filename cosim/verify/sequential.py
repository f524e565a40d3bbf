"""Campaigns sized to decide: ``ins-cosim verify --until-decided`` and its sequential rule.

A fixed campaign judges each requirement once, on n runs, at the requirement's
confidence γ, so a wrong verdict has probability at most α = 1 - γ: "satisfied" is
wrong only when the true statistic is above the limit and the upper confidence bound
fell below it, "violated" only when the true statistic is at or below the limit and the
lower bound rose above it; each of the two one-sided bounds fails with probability
<= α, and only one of them can produce a wrong verdict for a given truth.

Judging again at γ after each batch of runs and stopping at the first decision is not
valid: every look is another chance of a wrong verdict, and the chances add up (with
looks every 5 runs up to 200, a normal-theory RMS 10 % above its limit is called
satisfied in about 9 % of campaigns at γ = 95 %; tests/verify/test_sequential.py shows it).

**The rule: alpha spending over planned looks.** The looks are fixed before the first
run: n_1 = the first batch (``--runs``, else ``[campaign] runs``), doubling
(n_{j+1} = 2 n_j) while below the cap N = ``--max-runs``, and a last look at N (a doubled
look within 1.5 n of N is dropped, so the last batch is not tiny). Requirement r, with
α_r = 1 - γ_r, is judged at look j on the first n_j runs at confidence 1 - α_{r,j}, with
the linear spending function of Lan and DeMets::

    α_{r,j} = α_r (n_j - n_{j-1}) / N          (n_0 = 0),   sum_j α_{r,j} = α_r

and its first decision (satisfied or violated) is final: once decided it stays decided
and is not judged again; the campaign goes on only for the requirements still
undecided, and stops when none is left or after the look at N.

*Proof sketch.* Fix a requirement and its true statistic. A wrong final verdict is a
wrong verdict at the look where it was decided, so it implies that at some look j the
one-sided bound that matters failed (the event E_j). Each E_j has probability
<= α_{r,j} whatever happened at the other looks (the bound at look j is a valid bound
for the n_j runs, which are independent runs of the scenario's distribution, whatever
the stopping rule did), so by the union bound
``P(wrong) <= P(E_1 or ... or E_K) <= sum_j α_{r,j} = α_r``. No independence between
looks is needed, and the rule is conservative (the looks are strongly correlated). As
for fixed campaigns, the guarantee is per requirement.

The runs are those of a fixed campaign: run i has the seeds of run i of any campaign of
the same seed (:mod:`cosim.verify.seeds`), so the first n runs of an until-decided
campaign are ``verify --runs n``. Each look calls
:func:`cosim.verify.campaign.run_campaign` with ``resume``, so ``--resume`` and
``--cluster`` work as for fixed campaigns; the design is kept in ``sequential.json`` in
the report folder and ``--resume`` refuses to change it.

**Stratified scenarios** (``[campaign] stratify``). A Latin hypercube is drawn over a
known number of runs, and a sequential campaign does not know how many it will make. Its
design is therefore one hypercube per look batch (:func:`cosim.verify.seeds.design_batches`
with the looks): batch j, runs n_{j-1} .. n_j - 1, is a hypercube of n_j - n_{j-1} runs
from stream j of the campaign seed. The first batch is the design of ``verify --runs
n_1`` (stream 0 over n_1 runs), so the first look is that fixed campaign, run for run, as
for an unstratified scenario; the later looks are not the fixed campaign of n_j runs (that
would be one hypercube over n_j). The batch ends are in ``sequential.json`` and
``campaign.json`` (``strata``), so ``--resume`` continues with the same draws, and
:func:`run_alone` (``verify --until-decided --runs n_1 --max-runs N --only-run I``) reruns
run I with the draws it has in the campaign.

*What the design does to the bounds.* Every bound of :mod:`cosim.verify.statistics`
assumes independent runs. Within a batch the runs are not independent: each stratified
component has exactly one run in each of the batch's probability strata. Each run is
still exactly N(0, 1) per component (its stratum is uniform over the strata, its place
inside uniform), and the batches are independent of each other and of the stopping (a
batch's draws follow from the seed alone). Every statistic judged is a mean over the runs
of some function g of the run, or is decided by one (the mean square under ``rms``, the
pass fraction under ``pass_rate``, the count of runs below a level under ``p<q>`` and
``max``). Over a hypercube of n runs the variance of such a mean is, for large n, that
of independent runs less the variance of g's additive part in the stratified draws,
divided by n (Stein 1987); it is at most that of independent runs when g is monotone in
each draw (McKay, Beckman and Conover 1979), and never more than sigma^2 / (n - 1) for
any g (Owen, *Monte Carlo theory, methods and examples*, Proposition 10.4): a hypercube
is never worse than independent runs with one run fewer. Stratification is used where a
metric grows with a drawn turn-on error (a level error follows a drawn bias), i.e. where g
has a large additive part: there the statistic scatters less than the bounds assume, so
the bounds are conservative (they cover more often than stated, and are wider than they
need be), to the extent that a smaller variance means smaller tails (asymptotically it
does: the mean over a hypercube is asymptotically normal, Owen 1992). They are not
exact: the distribution of the statistic is no longer exactly chi-square or binomial,
and for a metric with no additive part in the draws its variance can exceed the
independent one by the factor n / (n - 1) (3 % for a 30-run batch). The sequential rule
needs nothing beyond this: each look's bound is as valid as a fixed stratified
campaign's, and the union bound over the looks holds as before. Simulated
(tests/verify/test_sequential_strata.py, 4000 campaigns per case, looks 20, 40, 80, 160, 320,
metrics ``|0.95 z + 0.31 e|`` with z the stratified draw and e independent): an RMS 10 %
above its limit is called satisfied in 0 of the campaigns on batch designs (0.2 % with z
drawn independently), a p95 exactly at its limit violated in 0.03 % (2.6 %).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from cosim.scenario import Scenario
from cosim.verify.campaign import (
    MANIFEST,
    RUNS_DIR,
    Campaign,
    CampaignError,
    prepare,
    run_campaign,
)
from cosim.verify.lock import holding_report_folder
from cosim.verify.pool import WorkerPool, keeps_workers
from cosim.verify.records import read_records
from cosim.verify.requirements import (
    SATISFIED,
    UNDECIDED,
    VIOLATED,
    Requirement,
    RunMetric,
    Verdict,
)
from cosim.verify.seeds import STRATIFY_RULE
from cosim.verify.statistics import judge

__all__ = [
    "DEFAULT_CONFIDENCE",
    "RULE",
    "SEQUENTIAL_FILE",
    "Looks",
    "default_max_runs",
    "first_decisions",
    "fixed_campaign_folder",
    "judge_at",
    "judge_sequentially",
    "plan_looks",
    "requirement_confidence",
    "run_alone",
    "run_until_decided",
    "runs_taken",
]

#: Confidence of a requirement that states none.
DEFAULT_CONFIDENCE = 0.95
#: The rule in one line, recorded in the report.
RULE = (
    "alpha spending over planned looks (Lan-DeMets linear spending): requirement r is "
    "judged at look j on the first n_j runs at confidence 1 - alpha_r (n_j - n_{j-1}) / "
    "n_K, its first decision is final; union bound: P(wrong verdict) <= alpha_r = 1 - "
    "confidence_r"
)
#: The design of an until-decided campaign, in its report folder.
SEQUENTIAL_FILE = "sequential.json"
FORMAT = "ins-cosim-sequential/1"
#: ``--max-runs`` when not given: the first batch times this (four doublings).
MAX_RUNS_FACTOR = 16

_CODES = {SATISFIED: 1, VIOLATED: -1, UNDECIDED: 0}


@dataclass(frozen=True)
class Looks:
    """The planned looks of a sequential campaign.

    Attributes
    ----------
    runs : tuple of int
        Run counts n_1 < n_2 < ... < n_K at which the requirements are judged; n_K is
        the cap.
    """

    runs: tuple[int, ...]

    def __post_init__(self) -> None:
        r = self.runs
        if not r or r[0] < 1 or any(b <= a for a, b in zip(r, r[1:], strict=False)):
            raise ValueError(f"looks must be increasing run counts >= 1, got {r}")

    @property
    def cap(self) -> int:
        """The last look (the most runs the campaign makes)."""
        return self.runs[-1]

    def alphas(self, alpha: float) -> np.ndarray:
        """Alpha spent at each look (linear spending), summing to ``alpha``.

        Parameters
        ----------
        alpha : float
            The requirement's total error probability, 1 - confidence.

        Returns
        -------
        ndarray, shape (K,)
            ``alpha (n_j - n_{j-1}) / n_K``.
        """
        n = np.asarray(self.runs, dtype=float)
        return alpha * np.diff(n, prepend=0.0) / n[-1]

    def confidences(self, confidence: float) -> np.ndarray:
        """Confidence of the judgement at each look.

        Parameters
        ----------
        confidence : float
            The requirement's confidence γ (overall, over all looks).

        Returns
        -------
        ndarray, shape (K,)
            ``1 - alphas(1 - γ)``.
        """
        return 1.0 - self.alphas(1.0 - confidence)


def default_max_runs(first: int) -> int:
    """``--max-runs`` when not given: 16 times the first batch.

    Parameters
    ----------
    first : int
        Runs of the first look.

    Returns
    -------
    int
    """
    return MAX_RUNS_FACTOR * int(first)


def plan_looks(first: int, max_runs: int) -> Looks:
    """Looks doubling from ``first`` up to ``max_runs`` (the last look).

    A doubled look above ``max_runs / 1.5`` is dropped, so that the last batch has at
    least half the runs of the look before it.

    Parameters
    ----------
    first : int
        Runs of the first look, >= 1.
    max_runs : int
        The cap, >= 1; ``max_runs <= first`` gives one look at ``max_runs`` (a fixed
        campaign).

    Returns
    -------
    Looks

    Raises
    ------
    CampaignError
        ``first`` or ``max_runs`` below 1.
    """
    if first < 1:
        raise CampaignError(f"--runs (the first look) must be >= 1, got {first}")
    if max_runs < 1:
        raise CampaignError(f"--max-runs must be >= 1, got {max_runs}")
    looks = []
    n = int(first)
    while n < max_runs and 1.5 * n <= max_runs:
        looks.append(n)
        n *= 2
    looks.append(int(max_runs))
    return Looks(tuple(looks))


def requirement_confidence(req: Requirement) -> float:
    """The confidence a requirement is judged at (its own, else 0.95).

    Parameters
    ----------
    req : Requirement
        The requirement.

    Returns
    -------
    float
    """
    return float(req.confidence) if req.confidence is not None else DEFAULT_CONFIDENCE


def judge_at(req: Requirement, metrics: Sequence[RunMetric | None], confidence: float) -> Verdict:
    """The verdict of a requirement on some runs, at a given confidence.

    Parameters
    ----------
    req : Requirement
        The requirement.
    metrics : sequence of RunMetric or None, shape (n_runs,)
        One per run, None for a failed run.
    confidence : float
        Confidence of the statistic's bounds, instead of the requirement's.

    Returns
    -------
    Verdict
        As :func:`cosim.verify.statistics.judge`, without runs-needed advice (a look's
        confidence is not the requirement's).
    """
    return judge(req, metrics, confidence=confidence, advise=False)


@dataclass
class SequentialVerdict:
    """A requirement's verdict under the sequential rule.

    Attributes
    ----------
    verdict : Verdict
        The final verdict: the one of the deciding look, else of the last look made.
    look : int or None
        0-based index of the deciding look; None when undecided.
    runs : int
        Runs the verdict is based on (``n`` of the deciding or last look).
    confidence : float
        Confidence the verdict was judged at (at that look).
    per_look : list of str
        The verdict at each look made, up to the deciding one.
    """

    verdict: Verdict
    look: int | None
    runs: int
    confidence: float
    per_look: list[str]


def judge_sequentially(
    req: Requirement, metrics: Sequence[RunMetric | None], looks: Looks
) -> SequentialVerdict:
    """Judge one requirement at every look its runs reach; its first decision is final.

    Parameters
    ----------
    req : Requirement
        The requirement.
    metrics : sequence of RunMetric or None, shape (n_runs,)
        Its metric in runs 0, 1, ... (None: a failed run); looks beyond ``n_runs`` are
        not made.
    looks : Looks
        The planned looks.

    Returns
    -------
    SequentialVerdict
    """
    conf = looks.confidences(requirement_confidence(req))
    per_look: list[str] = []
    last: tuple[Verdict, int, float] | None = None
    for j, n in enumerate(looks.runs):
        if n > len(metrics):
            break
        v = judge_at(req, metrics[:n], float(conf[j]))
        per_look.append(v.verdict)
        last = (v, n, float(conf[j]))
        if v.verdict != UNDECIDED:
            return SequentialVerdict(v, j, n, float(conf[j]), per_look)
    if last is None:
        raise ValueError(f"{len(metrics)} runs reach no look of {looks.runs}")
    return SequentialVerdict(last[0], None, last[1], last[2], per_look)


def first_decisions(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sequential rule on many campaigns at once: the first decision is final.

    Parameters
    ----------
    codes : ndarray of int, shape (m, K)
        Verdict of campaign i at look j: +1 satisfied, -1 violated, 0 undecided.

    Returns
    -------
    final : ndarray of int, shape (m,)
        The first non-zero code of each row (0 when none).
    look : ndarray of int, shape (m,)
        Its look index (-1 when undecided).
    """
    codes = np.asarray(codes)
    decided = codes != 0
    any_decided = decided.any(axis=1)
    first = np.argmax(decided, axis=1)
    final = np.where(any_decided, codes[np.arange(codes.shape[0]), first], 0)
    return final, np.where(any_decided, first, -1)


# ------------------------------------------------------------------------ the campaign
def _stratified_design(looks: Looks, stratify: Sequence[str]) -> dict[str, Any] | None:
    """The stratified design of the campaign (one hypercube per look batch), or None."""
    if not stratify:
        return None
    return {"parameters": list(stratify), "batches": list(looks.runs), "rule": STRATIFY_RULE}


def _design(
    looks: Looks,
    reqs: Sequence[Requirement],
    seed: int,
    first: int,
    max_runs: int,
    stratify: Sequence[str] = (),
) -> dict[str, Any]:
    out = {
        "format": FORMAT,
        "rule": RULE,
        "first": first,
        "max_runs": max_runs,
        "seed": seed,
        "looks": list(looks.runs),
        "requirements": {
            r.id: {
                "confidence": requirement_confidence(r),
                "alpha_per_look": [float(a) for a in looks.alphas(1.0 - requirement_confidence(r))],
            }
            for r in reqs
        },
    }
    strata = _stratified_design(looks, stratify)
    if strata is not None:
        out["stratified"] = strata
    return out


def _read_design(out: Path) -> dict[str, Any]:
    file = out / SEQUENTIAL_FILE
    if not file.is_file():
        what = "a fixed campaign" if (out / MANIFEST).is_file() else "no campaign"
        raise CampaignError(
            f"{out}: {what} to resume with --until-decided (no {SEQUENTIAL_FILE}); drop "
            f"--until-decided or --resume"
        )
    old = json.loads(file.read_text())
    if old.get("format") != FORMAT:
        raise CampaignError(f"{file}: not written by this version of ins-cosim")
    return old


def _pct(c: float) -> str:
    """A confidence in per cent (``99.6875 %``)."""
    return f"{100 * c:.6g} %"


def _look_line(j: int, looks: Looks, judged: list[tuple[Requirement, SequentialVerdict]]) -> str:
    """What look j decided, for the requirements judged at it."""
    decided = [f"{r.id} {sv.verdict.verdict}" for r, sv in judged if sv.look == j]
    open_ = [r.id for r, sv in judged if sv.look is None]
    confs = sorted({_pct(sv.confidence) for _, sv in judged})
    head = f"look {j + 1} of {len(looks.runs)}: {looks.runs[j]} runs, judged at {', '.join(confs)}"
    parts = [head, f"decided: {', '.join(decided) or 'none'}"]
    if open_:
        parts.append(f"undecided: {', '.join(open_)}")
    return "; ".join(parts)


@holding_report_folder("out_dir")  # one campaign at a time in the folder, over all looks
@keeps_workers  # one pool for all looks: its processes and built blocks stay
def run_until_decided(
    scenario: str | Path | Scenario,
    out_dir: str | Path,
    *,
    runs: int | None = None,
    max_runs: int | None = None,
    seed: int | None = None,
    workers: int | None = None,
    cluster: str | None = None,
    fmu_dir: str | Path | None = None,
    resume: bool = False,
    progress: bool = True,
    echo: Callable[[str], None] | None = None,
    pool: WorkerPool | None = None,
) -> Campaign:
    """Add runs in batches until every requirement is decided or the cap is reached.

    Parameters
    ----------
    scenario : str or Path
        Scenario file with ``[[requirements]]`` (a ``[campaign] stratify`` design is drawn
        per look batch, see the module docstring).
    out_dir : str or Path
        Report folder (as :func:`cosim.verify.campaign.run_campaign`), with
        ``sequential.json``.
    runs : int, optional
        Runs of the first look (default ``[campaign] runs``).
    max_runs : int, optional
        The cap, the last look (default 16 times the first look).
    seed : int, optional
        Campaign seed (default ``[campaign] seed``; on resume, the campaign's).
    workers : int, optional
        Local worker processes.
    cluster : str, optional
        Address of a Dask scheduler.
    fmu_dir : str or Path, optional
        Run built-in models from the FMUs in this folder.
    resume : bool
        Continue an interrupted until-decided campaign in ``out_dir`` (same design).
    progress : bool
        Progress bar on stderr.
    echo : callable, optional
        Called with one line per look (what was decided).
    pool : cosim.verify.pool.WorkerPool, optional
        The worker processes of every look (default: one pool of ``workers``, kept
        from the first look to the last and closed at the end).

    Returns
    -------
    Campaign
        The runs made; ``verdicts`` are the sequential verdicts (each with the look that
        decided it), ``execution["sequential"]`` the rule, looks, alpha per look and the
        runs each requirement took.

    Raises
    ------
    ScenarioError, FmuError, CampaignError
        Bad input, or a changed design on resume.
    CampaignInterrupted
        On Ctrl-C; the finished runs are on disk (continue with ``resume``).
    """
    out = Path(out_dir)
    prep = prepare(scenario, fmu_dir)
    stratify = prep.settings.stratify
    old = _read_design(out) if resume else None
    if seed is None:
        seed = int(old["seed"]) if old is not None else prep.settings.seed
    if runs is None:
        runs = int(old["first"]) if old is not None else prep.settings.runs
    if max_runs is None:
        max_runs = int(old["max_runs"]) if old is not None else default_max_runs(runs)
    looks = plan_looks(runs, max_runs)
    design = _design(looks, prep.requirements, seed, runs, max_runs, stratify)
    if old is not None:
        for key in ("looks", "seed", "requirements", "stratified"):
            if old.get(key) != design.get(key):
                raise CampaignError(
                    f"{out / SEQUENTIAL_FILE}: cannot resume: {key} was {old.get(key)!r}, now "
                    f"{design.get(key)!r} (the looks are fixed before the first run); run "
                    f"without --resume to start over"
                )
        started = int(json.loads((out / MANIFEST).read_text())["runs"])
    else:
        started = 0
        out.mkdir(parents=True, exist_ok=True)
        (out / SEQUENTIAL_FILE).write_text(json.dumps(design, indent=2) + "\n")

    reqs = prep.requirements
    final: dict[str, SequentialVerdict] = {}
    campaign: Campaign | None = None
    ran = 0
    for j, n in enumerate(looks.runs):
        if n < started:  # a look an interrupted campaign passed: its runs are on disk
            by_index = read_records(out / RUNS_DIR, n)
            if len(by_index) < n:
                raise CampaignError(f"{out / RUNS_DIR}: runs of look {j + 1} ({n} runs) missing")
            records = [by_index[i] for i in range(n)]
            campaign = None
        else:
            campaign = run_campaign(
                prep,
                out,
                runs=n,
                seed=seed,
                workers=workers,
                cluster=cluster,
                fmu_dir=fmu_dir,
                resume=resume or j > 0,
                progress=progress,
                strata=looks.runs,
                pool=pool,
            )
            ran += int(campaign.execution["runs_this_session"])
            records = campaign.records
        judged = []
        for req in reqs:
            if req.id in final and final[req.id].look is not None:
                continue  # decided at an earlier look: stays decided
            metrics = [r.metrics.get(req.id) for r in records]
            final[req.id] = judge_sequentially(req, metrics, looks)  # looks 1 .. j + 1
            judged.append((req, final[req.id]))
        if echo is not None:
            echo(_look_line(j, looks, judged))
        if all(final[r.id].look is not None for r in reqs):
            break
    if campaign is None:
        raise CampaignError(f"{out}: the campaign on disk does not match its design; start over")
    campaign.execution["resumed"] = resume
    return _finish(campaign, reqs, final, looks, ran, _stratified_design(looks, stratify))


def _overall_claim(claim: str, look: float, overall: float) -> str:
    """The claim of a look's verdict, with the confidence the sequential rule gives it.

    The bound of the deciding look is at the look's confidence; what the rule shows, by
    the union bound over the looks, holds at the requirement's (lower) confidence.
    """
    if not claim:
        return claim
    at_look, at_rule = f"{100 * look:g} % confidence", f"{100 * overall:g} % confidence"
    note = f"{at_rule} over the looks of --until-decided (this look's bound at {100 * look:g} %)"
    if at_look in claim:
        return claim.replace(at_look, note, 1)
    return f"{claim} ({note})"


def _finish(
    campaign: Campaign,
    reqs: Sequence[Requirement],
    final: dict[str, SequentialVerdict],
    looks: Looks,
    ran: int,
    stratified: dict[str, Any] | None = None,
) -> Campaign:
    """The campaign with the sequential verdicts and the design in ``execution``."""
    verdicts = []
    taken = {}
    k = len(looks.runs)
    for req in reqs:
        sv = final[req.id]
        v = replace(sv.verdict, details=dict(sv.verdict.details))
        if sv.look is not None:
            v.reason = (
                f"decided at look {sv.look + 1} of {k} ({sv.runs} runs, judged at "
                f"{_pct(sv.confidence)} confidence by alpha spending): {v.reason}"
            )
        else:
            v.reason = (
                f"undecided at every look up to {sv.runs} runs (the last judged at "
                f"{_pct(sv.confidence)} confidence): {v.reason}"
            )
        if sv.look is not None:  # a one-sided bound decided it: the rule's confidence
            v.claim = _overall_claim(v.claim, sv.confidence, requirement_confidence(req))
        v.details.update(
            sequential_look=None if sv.look is None else sv.look + 1,
            sequential_runs=sv.runs,
            sequential_confidence=sv.confidence,
        )
        verdicts.append(v)
        taken[req.id] = {
            "verdict": v.verdict,
            "look": None if sv.look is None else sv.look + 1,
            "runs": sv.runs,
            "confidence": sv.confidence,
        }
    campaign.verdicts = verdicts
    alphas = {
        f"{c:g}": [round(float(a), 10) for a in looks.alphas(1 - c)]
        for c in sorted({requirement_confidence(r) for r in reqs})
    }
    campaign.execution.update(
        runs_this_session=ran,
        sequential={
            "rule": RULE,
            "looks": list(looks.runs),
            "max_runs": looks.cap,
            "alpha_per_look": alphas,
            "requirements": taken,
            "stopped_at": len(campaign.records),
            "stratified": stratified,
        },
    )
    return campaign


def run_alone(
    scenario: str | Path | Scenario,
    out_dir: str | Path,
    only_runs: Sequence[int],
    *,
    runs: int | None = None,
    max_runs: int | None = None,
    seed: int | None = None,
    workers: int | None = None,
    cluster: str | None = None,
    fmu_dir: str | Path | None = None,
    progress: bool = True,
) -> Campaign:
    """Run some runs of an until-decided campaign alone, with the numbers they have in it.

    ``verify --until-decided --only-run I``: the looks are planned from ``runs`` and
    ``max_runs`` as by :func:`run_until_decided` (give the campaign's), so run I gets the
    seeds and, in a stratified scenario, the draws of its look batch. The runs are judged
    as by ``verify --only-run`` (a fixed campaign of those runs, at full confidence).

    Parameters
    ----------
    scenario : str or Path
        Scenario file with ``[[requirements]]``.
    out_dir : str or Path
        Report folder (a new campaign of these runs; an until-decided one there is
        replaced).
    only_runs : sequence of int
        The runs, each below the cap.
    runs : int, optional
        Runs of the first look (default ``[campaign] runs``).
    max_runs : int, optional
        The cap (default 16 times the first look).
    seed : int, optional
        Campaign seed (default ``[campaign] seed``).
    workers : int, optional
        Local worker processes.
    cluster : str, optional
        Address of a Dask scheduler.
    fmu_dir : str or Path, optional
        Run built-in models from the FMUs in this folder.
    progress : bool
        Progress bar on stderr.

    Returns
    -------
    Campaign
        As :func:`cosim.verify.campaign.run_campaign` with ``only_runs``.

    Raises
    ------
    ScenarioError, FmuError, CampaignError
        Bad input, or a run beyond the cap.
    """
    prep = prepare(scenario, fmu_dir)
    first = int(runs) if runs is not None else prep.settings.runs
    looks = plan_looks(first, max_runs if max_runs is not None else default_max_runs(first))
    fixed_campaign_folder(out_dir, resume=False)
    return run_campaign(
        prep, out_dir, runs=looks.cap, seed=seed, workers=workers, cluster=cluster,
        fmu_dir=fmu_dir, progress=progress, only_runs=list(only_runs), strata=looks.runs,
    )  # fmt: skip


def runs_taken(sequential: dict[str, Any]) -> list[str]:
    """The runs each requirement took, as printed by ``verify --until-decided``.

    Parameters
    ----------
    sequential : dict
        ``campaign.execution["sequential"]`` of :func:`run_until_decided`.

    Returns
    -------
    list of str
        A heading and one line per requirement.
    """
    looks = ", ".join(str(n) for n in sequential["looks"])
    out = [f"runs to decide (looks at {looks} runs; {sequential['stopped_at']} runs made):"]
    for rid, r in sequential["requirements"].items():
        if r["look"] is None:
            out.append(
                f"  {rid}: not decided by {r['runs']} runs (the cap is {sequential['max_runs']})"
            )
        else:
            out.append(f"  {rid}: {r['verdict']} after {r['runs']} runs (look {r['look']})")
    return out


def fixed_campaign_folder(out_dir: str | Path, resume: bool) -> None:
    """Before a fixed campaign in ``out_dir``: refuse to resume an until-decided one.

    A fixed ``--resume`` would judge its runs at full confidence after the looks, the
    naive re-test the sequential rule avoids. A new fixed campaign (no ``resume``)
    replaces the sequential one: its design file is removed.

    Parameters
    ----------
    out_dir : str or Path
        The report folder.
    resume : bool
        Whether the fixed campaign resumes.

    Raises
    ------
    CampaignError
        ``resume`` of an until-decided campaign.
    """
    design = Path(out_dir) / SEQUENTIAL_FILE
    if resume and design.is_file():
        raise CampaignError(
            f"{out_dir}: an --until-decided campaign ({SEQUENTIAL_FILE}); resume it with "
            f"--until-decided --resume"
        )
    if not resume:
        design.unlink(missing_ok=True)
