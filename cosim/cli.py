"""The command line: ``ins-cosim`` and its subcommands, and how it reports a user's mistake.

Subcommands: ``run | check | fmus | verify | plan | characterize | place | check-fmu |
export-ssp | reproduce``.

A user's mistake (bad scenario, missing FMU, failing block, bad option) prints one
message naming the file, key, block or variable, and exits non-zero without a traceback:
3 for bad input, 4 for a run that stopped (its partial results are still written);
``verify`` uses 1 and 2 for violated and undecided requirements.
"""

from __future__ import annotations

import copy
import sys
import warnings
from pathlib import Path

import click

from cosim.errors import SimulationError, UserError

DEFAULT_FMU_DIR = Path("fmus/build")


def _fail(exc: UserError) -> None:
    click.echo(f"error: {exc}", err=True)
    sys.exit(exc.exit_code)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
    click.echo(f"warning: {message}", err=True)


def _echo_sources(scenario) -> None:  # noqa: ANN001  (a cosim.scenario.Scenario)
    """One line per block: the FMU file it runs from, or in-process and its model or class."""
    width = max(len(name) for name in scenario.blocks)
    for spec in scenario.blocks.values():
        where = f"FMU {spec.source}" if spec.kind == "fmu" else f"in-process {spec.source}"
        click.echo(f"  {spec.name:<{width}}  {where}")


def _check_roles(scenario, master) -> None:  # noqa: ANN001  (Scenario, Master)
    """Refuse required role inputs left unconnected and log replays out of step with each
    other (cosim.sensors.pairing); terminates the master when it does."""
    from cosim.interop.interfaces import check_role_inputs
    from cosim.sensors.pairing import check_log_pairs

    try:
        check_role_inputs(scenario, master.system, master.metadata.get("unconnected", {}))
        check_log_pairs(scenario, master)
    except BaseException:
        master.terminate()
        raise


def _output_folder(path: Path, option: str) -> None:
    """Refuse, before anything runs, an output folder that names an existing file (or lies
    under one): the results would be lost after the run."""
    for p in (path, *path.parents):
        if p.exists() and not p.is_dir():
            what = "is" if p == path else f"is under '{p}', which is"
            raise UserError(f"{option} '{path}' {what} an existing file; give a folder")


def _echo_running(scenario, info: dict) -> None:  # noqa: ANN001  (a Scenario)
    """The line a run starts with, and where each block runs from."""
    click.echo(
        f"running '{scenario.name}': {info['blocks']} blocks, {info['n_steps']} steps of "
        f"{info['step']:g} s ({info['coupling']})"
    )
    _echo_sources(scenario)


def _run_here(scenario, fmu_dir: Path | None, overrides: dict):  # noqa: ANN001, ANN202
    """Build and run a Scenario in this process (:func:`cosim.runs.make_run`)."""
    from cosim.runs import make_run

    def announce(assembly) -> None:  # noqa: ANN001  (a cosim.runs.Assembly)
        master, built = assembly.master, assembly.scenario  # FMU paths as --fmu-dir set them
        _check_roles(built, master)
        s = master.settings
        info = {"blocks": len(master.system.blocks), "n_steps": s.n_steps}
        _echo_running(built, dict(info, step=s.step, coupling=s.coupling))

    return make_run(scenario, fmu_dir=fmu_dir, overrides=overrides, before=announce)


def _load_scenario(path: Path):  # noqa: ANN202  (a cosim.scenario.Scenario)
    """A scenario file (``.toml``) or an SSP archive (``.ssp``, cosim.interop.ssp_import)."""
    if Path(path).suffix.lower() == ".ssp":
        from cosim.interop.ssp_import import load_ssp

        return load_ssp(path)
    from cosim.scenario import load_scenario

    return load_scenario(path)


def _stop_override(scenario, stop: str | None) -> dict:  # noqa: ANN001  (a Scenario)
    """``--stop`` read and checked as ``--stop`` (not as ``master.stop``)."""
    from cosim.errors import ScenarioError
    from cosim.scenario import parse_seconds

    if stop is None:
        return {}
    value = parse_seconds(stop, str(scenario.path), "--stop")
    try:
        scenario.master_settings(stop=value)
    except ScenarioError as exc:
        if exc.key != "master.stop":
            raise
        message = exc.message.replace("master.stop", "--stop")
        raise ScenarioError(message, file=exc.file, key="--stop") from None
    return {"stop": value}


def _check_requirements(scenario, master) -> int:  # noqa: ANN001  (Scenario, Master)
    """Check the ``[campaign]`` and ``[[requirements]]`` tables as ``verify`` reads them.

    Returns the number of requirements (0 when the scenario has none).
    """
    if "requirements" not in scenario.raw and "campaign" not in scenario.raw:
        return 0
    from cosim.verify.campaign import parse_campaign
    from cosim.verify.tables import check_tables

    checked = check_tables(scenario, parse_campaign(scenario), master, required=False)
    return len(checked.requirements)


class _Command(click.Command):
    """Every command exits 3 on a usage error (``verify`` uses 1 and 2 for verdicts)."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        try:
            return super().parse_args(ctx, args)
        except click.UsageError as exc:
            exc.exit_code = 3
            raise


class _Group(click.Group):
    command_class = _Command


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="ins-cosim")
def main() -> None:
    """Co-simulation workbench for the initial alignment of inertial navigation systems."""
    warnings.showwarning = _show_warning


@main.command()
@click.argument("scenario", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out",
    type=click.Path(path_type=Path),
    required=True,
    help="Folder for results.csv, results.json and results.png.",
)
@click.option(
    "--fmu-dir",
    type=click.Path(path_type=Path),
    default=None,
    help="Run built-in models from the FMUs in this folder instead of in-process.",
)
@click.option("--stop", type=str, default=None, help="Override master.stop, e.g. '10 s'.")
@click.option("--plot/--no-plot", default=True, show_default=True, help="Write results.png.")
@click.option(
    "--isolate/--no-isolate",
    default=None,
    help="Run in a child process: an FMU that kills it (abort, a crash) leaves the results "
    "recorded up to then, and a note naming the block, the time and the signal. Default: "
    "isolated when an FMU was not built by ins-cosim (docs/foreign_fmus.md).",
)
def run(
    scenario: Path,
    out: Path,
    fmu_dir: Path | None,
    stop: str | None,
    plot: bool,
    isolate: bool | None,
) -> None:
    """Run SCENARIO (a .toml scenario or an SSP 1.0 .ssp archive) once and write its results
    to --out."""
    try:
        _output_folder(out, "--out")
        sc = _load_scenario(scenario)
        overrides = _stop_override(sc, stop)
        foreign: dict[str, str] = {}
        if isolate is None:
            from cosim.foreign import foreign_fmus

            foreign = foreign_fmus(sc, fmu_dir)
            isolate = bool(foreign)
        if isolate:
            from cosim.isolate import run_isolated

            def started(info: dict) -> None:
                _echo_running(sc, info)
                if foreign:
                    click.echo(
                        f"  in a child process: FMU(s) not built by ins-cosim "
                        f"({', '.join(foreign)}); --no-isolate runs here"
                    )

            result = run_isolated(
                sc.path, fmu_dir=fmu_dir, overrides=overrides, check=_check_roles,
                started=started, loader=_load_scenario,
            )  # fmt: skip
        else:
            result = _run_here(sc, fmu_dir, overrides)
    except SimulationError as exc:
        click.echo(f"error: {exc}", err=True)
        if exc.result is not None and len(exc.result.data):
            csv, _ = exc.result.save(out)
            click.echo(f"results recorded up to the failure are in {csv}", err=True)
        sys.exit(exc.exit_code)
    except UserError as exc:
        _fail(exc)
    from cosim.verify.consistency import check_run

    consistency = check_run(result)
    result.metadata["consistency"] = consistency.to_dict()
    csv, meta_file = result.save(out)
    click.echo(f"wrote {csv} ({len(result.data)} rows) and {meta_file}")
    for line in consistency.lines():
        click.echo(line)
    if plot:
        from cosim.verify.plots import plot_result

        png = plot_result(result, out / "results.png", title=sc.name)
        click.echo(f"wrote {png}")


@main.command()
@click.argument("scenario", type=click.Path(path_type=Path))
@click.option(
    "--fmu-dir",
    type=click.Path(path_type=Path),
    default=None,
    help="Check as if built-in models ran from the FMUs in this folder.",
)
def check(scenario: Path, fmu_dir: Path | None) -> None:
    """Validate SCENARIO (a .toml scenario or an .ssp archive: blocks, parameters, units,
    connections) without running it."""
    from cosim.runs import assemble

    try:
        sc = _load_scenario(scenario)
        assembly = assemble(sc, fmu_dir=fmu_dir)  # the recording's size checked too
        sc, master = assembly.scenario, assembly.master  # FMU paths as --fmu-dir set them
        system = master.system
        _check_roles(sc, master)
        try:
            master.warn_loops()
            n_reqs = _check_requirements(sc, master)
        finally:
            master.terminate()
    except UserError as exc:
        _fail(exc)
    reqs = f", {n_reqs} requirement(s)" if n_reqs else ""
    click.echo(
        f"{scenario}: OK - {len(system.blocks)} blocks, {len(system.connections)} scalar "
        f"connections, {master.settings.n_steps} steps{reqs}; stepping order: "
        f"{' -> '.join(master.order)}"
    )
    _echo_sources(sc)


@main.command()
@click.option(
    "--dir",
    "fmu_dir",
    type=click.Path(path_type=Path),
    default=DEFAULT_FMU_DIR,
    show_default=True,
    help="Folder of FMUs.",
)
@click.option("--build", is_flag=True, help="First build every built-in model into --dir.")
def fmus(fmu_dir: Path, build: bool) -> None:
    """List and validate (fmpy validate) the FMUs in --dir."""
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    from cosim.blocks import file_sha256
    from cosim.interop.packaging import REQUIREMENTS

    if build:
        from cosim.interop.packaging import build_all

        for path in build_all(fmu_dir):
            click.echo(f"built {path}")
    files = sorted(Path(fmu_dir).glob("*.fmu"))
    if not files:
        click.echo(
            f"error: no FMUs in {fmu_dir}; build ours with `ins-cosim fmus --build --dir "
            f"{fmu_dir}` (in a checkout, `make fmus` does the same into fmus/build)",
            err=True,
        )
        sys.exit(3)
    bad = 0
    python_fmus = []
    click.echo(f"{'FMU':<28} {'FMI':<4} {'GUID':<37} {'sha256':<13} problems")
    for f in files:
        try:
            problems = validate_fmu(str(f))
            md = read_model_description(str(f), validate=False)
        except Exception as exc:  # one unreadable file must not hide the others
            bad += 1
            click.echo(f"{f.name:<28} unreadable: {exc}")
            continue
        bad += bool(problems)
        if (md.generationTool or "").lower().startswith("pythonfmu"):
            python_fmus.append(f.name)
        digest = file_sha256(f)[:12]
        click.echo(f"{f.name:<28} {md.fmiVersion:<4} {md.guid:<37} {digest:<13} {len(problems)}")
        for p in problems:
            click.echo(f"    {p}")
    if python_fmus:
        click.echo(
            f"host requirements of {len(python_fmus)} FMU(s) made with PythonFMU (ours): the "
            f"Python interpreter that loads them needs {' and '.join(REQUIREMENTS)} "
            f"(pip install {' '.join(REQUIREMENTS)}); pythonfmu's runtime is inside each FMU"
        )
    sys.exit(1 if bad else 0)


@main.command()
@click.argument("scenario", type=click.Path(path_type=Path))
@click.option(
    "--report",
    "report_dir",
    type=click.Path(path_type=Path),
    required=True,
    help="Folder for report.html, junit.xml, report.json, metrics.csv and runs/.",
)
@click.option("--runs", type=int, default=None, help="Runs (default: [campaign] runs, else 1).")
@click.option(
    "--workers", type=int, default=None, help="Local worker processes (default: CPU count)."
)
@click.option(
    "--cluster", default=None, help="Dask scheduler address (tcp://host:8786) instead of workers."
)
@click.option("--seed", type=int, default=None, help="Campaign seed (default: [campaign] seed).")
@click.option(
    "--fmu-dir",
    type=click.Path(path_type=Path),
    default=None,
    help="Run built-in models from the FMUs in this folder instead of in-process.",
)
@click.option("--resume", is_flag=True, help="Keep the finished runs in --report, run the rest.")
@click.option(
    "--rerun-crashed",
    is_flag=True,
    help="With --resume: run again the runs recorded as crashed (their worker process died).",
)
@click.option("--progress/--no-progress", default=True, help="Progress bar on stderr.")
@click.option(
    "--only-run",
    "only_runs",
    type=int,
    multiple=True,
    help="Run only run I of the campaign of --runs runs (repeatable), with its seeds and draws.",
)
@click.option(
    "--until-decided",
    is_flag=True,
    help="Add runs in batches (--runs, then doubling) until every requirement is decided "
    "(alpha spending over the planned looks) or --max-runs is reached.",
)
@click.option(
    "--max-runs", type=int, default=None, help="Cap of --until-decided (default 16 x --runs)."
)
def verify(
    scenario: Path,
    report_dir: Path,
    runs: int | None,
    workers: int | None,
    cluster: str | None,
    seed: int | None,
    fmu_dir: Path | None,
    resume: bool,
    rerun_crashed: bool,
    progress: bool,
    only_runs: tuple[int, ...],
    until_decided: bool,
    max_runs: int | None,
) -> None:
    """Verify the requirements of SCENARIO over a Monte Carlo campaign.

    --only-run I reruns run I alone with the numbers it has in the whole campaign (the
    same --seed and --runs: stratified draws depend on the run count; a run of an
    --until-decided campaign: add --until-decided and its --runs and --max-runs).

    --resume keeps the runs recorded as crashed (their worker process died);
    --rerun-crashed runs them again.

    --until-decided judges at looks of --runs, 2 x --runs, ... up to --max-runs runs,
    each requirement at a confidence whose alphas sum to its own 1 - confidence, and
    stops when all are decided (docs/campaigns.md, "Campaigns sized to decide").

    Exit code: 0 all satisfied, 1 any violated, 2 any undecided (none violated),
    3 bad input, 130 interrupted (finished runs are kept: rerun with --resume).
    """
    from cosim.verify.campaign import CampaignInterrupted, run_campaign
    from cosim.verify.report import write_reports

    try:
        from cosim.scenario import load_scenario
        from cosim.verify.lock import report_folder_lock

        _output_folder(report_dir, "--report")
        if rerun_crashed and not resume:
            raise UserError("--rerun-crashed reruns the crashed runs of --resume: add --resume")
        click.get_current_context().with_resource(report_folder_lock(report_dir))  # one at a time
        sc = load_scenario(scenario)  # the one parse of this process (cosim.runs)
        shown = copy.deepcopy(sc)
        if fmu_dir is not None:
            shown.use_fmus(fmu_dir)
        _echo_sources(shown)
        if max_runs is not None and not until_decided:
            raise UserError("--max-runs is the cap of --until-decided: add --until-decided")
        if until_decided:
            from cosim.verify.sequential import run_alone, run_until_decided

            if only_runs and resume:
                raise UserError("--only-run and --resume cannot be combined")
            if only_runs:  # a run of an until-decided campaign, with its look batch's draws
                campaign = run_alone(
                    sc, report_dir, list(only_runs), runs=runs, max_runs=max_runs,
                    seed=seed, workers=workers, cluster=cluster, fmu_dir=fmu_dir,
                    progress=progress,
                )  # fmt: skip
            else:
                campaign = run_until_decided(
                    sc, report_dir, runs=runs, max_runs=max_runs, seed=seed,
                    workers=workers, cluster=cluster, fmu_dir=fmu_dir, resume=resume,
                    progress=progress, echo=click.echo,
                )  # fmt: skip
        else:
            from cosim.verify.sequential import fixed_campaign_folder

            fixed_campaign_folder(report_dir, resume)
            campaign = run_campaign(
                sc,
                report_dir,
                runs=runs,
                seed=seed,
                workers=workers,
                cluster=cluster,
                fmu_dir=fmu_dir,
                resume=resume,
                progress=progress,
                only_runs=list(only_runs) or None,
                rerun_crashed=rerun_crashed,
            )
        paths = write_reports(campaign)
    except UserError as exc:
        _fail(exc)
    except (CampaignInterrupted, KeyboardInterrupt) as exc:
        text = (
            str(exc)
            or f"interrupted: finished runs are kept in {report_dir}; continue with --resume"
        )
        if until_decided:
            text = text.replace("with --resume", "with --until-decided --resume")
        click.echo(text, err=True)
        sys.exit(130)
    failed = len(campaign.failed_runs)
    ran = len(campaign.records)
    of = "" if ran == campaign.settings.runs else f" of {campaign.settings.runs}"
    click.echo(
        f"{campaign.scenario['name']}: {ran} run(s){of}, {failed} failed, "
        f"campaign seed {campaign.settings.seed}"
    )
    for req, v in zip(campaign.requirements, campaign.verdicts, strict=True):
        click.echo(f"  {v.verdict.upper():<10} {req.id}: {v.reason}")
    from cosim.verify.consistency_report import consistency_lines, consistency_section

    for line in consistency_lines(consistency_section(campaign)):
        click.echo(line)
    if "sequential" in campaign.execution:
        from cosim.verify.sequential import runs_taken

        click.echo("\n".join(runs_taken(campaign.execution["sequential"])))
    click.echo(f"wrote {paths['html']}, {paths['junit']} and {paths['json']}")
    sys.exit(campaign.exit_code)


@main.command()
@click.argument("scenario", type=click.Path(path_type=Path))
@click.option("--pilot", type=int, default=20, show_default=True, help="Pilot runs.")
@click.option("--seed", type=int, default=None, help="Campaign seed (default: [campaign] seed).")
@click.option(
    "--workers", type=int, default=None, help="Local worker processes (default: CPU count)."
)
@click.option(
    "--max-runs",
    type=int,
    default=None,
    help="Cap of the --until-decided prediction (default 16 x --pilot).",
)
@click.option(
    "--fmu-dir",
    type=click.Path(path_type=Path),
    default=None,
    help="Run built-in models from the FMUs in this folder instead of in-process.",
)
@click.option("--progress/--no-progress", default=True, help="Progress bar on stderr.")
def plan(
    scenario: Path,
    pilot: int,
    seed: int | None,
    workers: int | None,
    max_runs: int | None,
    fmu_dir: Path | None,
    progress: bool,
) -> None:
    """Run a pilot of SCENARIO and print, per requirement, the runs and time to decide it.

    The pilot is runs 0 .. --pilot - 1 of the campaign (its seed); nothing is written.
    Exit code 0, 3 bad input, 130 interrupted.
    """
    from cosim.verify.campaign import CampaignInterrupted
    from cosim.verify.plan import format_plan, make_plan

    try:
        if max_runs is not None and max_runs < 1:
            raise UserError(f"--max-runs must be >= 1, got {max_runs}")
        result = make_plan(
            scenario, pilot=pilot, seed=seed, workers=workers, fmu_dir=fmu_dir,
            max_runs=max_runs, progress=progress,
        )  # fmt: skip
    except UserError as exc:
        _fail(exc)
    except (CampaignInterrupted, KeyboardInterrupt):
        click.echo("interrupted", err=True)
        sys.exit(130)
    click.echo(format_plan(result))


@main.command("check-fmu")
@click.argument("fmu", type=click.Path(path_type=Path))
@click.option("--role", required=True, help="Role name (imu, motion, ...) or a role spec .toml.")
@click.option(
    "--rename",
    "rename_file",
    type=click.Path(path_type=Path),
    default=None,
    help="TOML file with the rename map to apply ([rename] or [blocks.<name>.rename]).",
)
@click.option("--block", default=None, help="Block name in the printed rename table.")
@click.option(
    "--scenario",
    "scenario",
    type=click.Path(path_type=Path),
    default=None,
    help="Print the edits that swap FMU in for --block of this scenario (block table, "
    "connection lines, entries to remove).",
)
def check_fmu(
    fmu: Path, role: str, rename_file: Path | None, block: str | None, scenario: Path | None
) -> None:
    """Report how FMU fills a role: every variable, units, capabilities, rename map.

    With --scenario, also the scenario edits of the swap, each ready to paste.
    Exit code 0 when it fills the role (with the printed rename map), 1 when it does not.
    """
    from cosim.interop.fmu_check import check_fmu as check_role
    from cosim.interop.fmu_check import format_report, read_rename_file

    try:
        rename = read_rename_file(rename_file) if rename_file is not None else None
        report = check_role(fmu, role, rename)
    except UserError as exc:
        _fail(exc)
    name = block or report.match.role.name
    click.echo(format_report(report, name))
    if scenario is not None:
        from cosim.interop.fmu_check import scenario_edits

        try:
            click.echo("\n".join(scenario_edits(report, scenario, name)))
        except UserError as exc:
            _fail(exc)
    sys.exit(0 if report.satisfied else 1)


@main.command()
@click.argument("log", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out",
    type=click.Path(path_type=Path),
    required=True,
    help="Folder for allan.csv, allan.png, characterization.json and imu_parameters.toml.",
)
@click.option(
    "--sample-rate", type=float, default=None, help="Log rate [Hz] (default: timestamps)."
)
@click.option("--jitter", type=float, default=0.05, show_default=True, help="Timestamp tolerance.")
@click.option("--drop-duplicates", is_flag=True, help="Drop rows repeating the previous row.")
@click.option(
    "--bootstrap",
    type=int,
    default=1000,
    show_default=True,
    help="Bootstrap refits of each axis's Allan variances (chi-square, Greenhall edf).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Bootstrap seed.")
def characterize(
    log: Path,
    out: Path,
    sample_rate: float | None,
    jitter: float,
    drop_duplicates: bool,
    bootstrap: int,
    seed: int,
) -> None:
    """Allan analysis of a static IMU LOG: noise terms, plot, StrapdownImu parameters.

    LOG may hold any of the six sensor columns (gyros only, one axis, ...); it is read
    once in chunks, so a 24-hour log needs no more memory than a short one.
    """
    from cosim.sensors.report import characterize_log, write_outputs

    try:
        result = characterize_log(
            log,
            sample_rate=sample_rate,
            jitter=jitter,
            duplicates="drop" if drop_duplicates else "error",
            boot=bootstrap,
            seed=seed,
        )
    except UserError as exc:
        _fail(exc)
    paths = write_outputs(result, out)
    click.echo(paths["toml"].read_text().rstrip())
    click.echo(f"wrote {paths['png']}, {paths['csv']}, {paths['json']} and {paths['toml']}")


@main.command()
@click.argument("real_report", type=click.Path(path_type=Path))
@click.argument("campaign_report", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out",
    type=click.Path(path_type=Path),
    default=None,
    help="Folder for placement.md and placement.json (default: REAL_REPORT).",
)
def place(real_report: Path, campaign_report: Path, out: Path | None) -> None:
    """Place the real run of REAL_REPORT in CAMPAIGN_REPORT: its percentile per requirement.

    Both are `verify --report` folders with the same requirements. A real run outside the
    simulated distribution is stated as a finding; the exit code is 0 (3: bad input).
    """
    from cosim.sensors.placement import format_placement, place, read_report, write_placement

    try:
        placements = place(read_report(real_report), read_report(campaign_report))
    except UserError as exc:
        _fail(exc)
    text = format_placement(placements, str(real_report), str(campaign_report))
    paths = write_placement(placements, out or real_report, str(real_report), str(campaign_report))
    click.echo(text.rstrip())
    click.echo(f"wrote {paths['md']} and {paths['json']}")


@main.command("export-ssp")
@click.argument("scenario", type=click.Path(path_type=Path))
@click.argument("out", type=click.Path(path_type=Path))
@click.option(
    "--fmu-dir",
    type=click.Path(path_type=Path),
    default=DEFAULT_FMU_DIR,
    show_default=True,
    help="The FMUs of the built-in models (built by `make fmus`).",
)
@click.option(
    "--exclude",
    "exclude",
    multiple=True,
    help="Leave block BLOCK out (a Python block has no FMU); its connections are cut.",
)
def export_ssp(scenario: Path, out: Path, fmu_dir: Path, exclude: tuple[str, ...]) -> None:
    """Write SCENARIO's FMU blocks, connections and parameters as an SSP 1.0 archive OUT."""
    from cosim.interop.ssp import export_ssp as export

    try:
        result = export(scenario, out, fmu_dir, exclude=list(exclude))
    except UserError as exc:
        _fail(exc)
    for name in result.excluded:
        cut = [
            c
            for c in result.cut
            if name
            in (c.split("->")[0].split(".")[0].strip(), c.split("->")[1].split(".")[0].strip())
        ]
        click.echo(f"left out: block {name} ({len(cut)} connection(s) cut: {'; '.join(cut)})")
    for line in result.left_out:
        click.echo(f"left out: {line}")
    click.echo(
        f"wrote {result.path}: {len(result.components)} components, {result.connections} "
        f"scalar connections, {result.parameters} parameter values"
    )
    click.echo("SSP tools such as libcosim step it with Jacobi coupling (coupling = 'jacobi')")


@main.command()
@click.argument("name", required=False)
@click.option(
    "--out",
    type=click.Path(path_type=Path),
    default=None,
    help="Folder for plots and tables (default out/reproduce/NAME).",
)
@click.option("--runs", type=int, default=None, help="Monte Carlo runs (default: the docs').")
@click.option("--seed", type=int, default=None, help="Campaign seed (default: the docs').")
@click.option(
    "--update-docs",
    is_flag=True,
    help="Write the tables into the reproductions page between the NAME markers.",
)
@click.option("--update-readme", is_flag=True, hidden=True)  # deprecated: --update-docs
@click.option(
    "--run",
    "run_index",
    type=int,
    default=None,
    help="Rerun only run I of --case (same --runs and --seed) and print its numbers.",
)
@click.option(
    "--case",
    default=None,
    help="The case of --run (e.g. 'lever 20 flexure 10 ignored'; default: the main campaign).",
)
def reproduce(
    name: str | None,
    out: Path | None,
    runs: int | None,
    seed: int | None,
    update_docs: bool,
    update_readme: bool,
    run_index: int | None,
    case: str | None,
) -> None:
    """Reproduce a source paper (docs/reproductions.md): tables and plots.

    NAME is a registered reproduction (entry-point group ins_cosim.reproductions);
    without NAME the command lists them. Every run goes through the campaign engine of
    `verify`: `--run I` (with `--case`) reruns one run alone with the numbers it has in
    the whole reproduction.
    """
    from cosim import reproductions

    if name is None:
        for known, module in reproductions.names().items():
            click.echo(f"{known}  ({module})")
        return
    if update_readme:
        click.echo("warning: --update-readme is deprecated; it is --update-docs now", err=True)
        update_docs = True
    try:
        rep = reproductions.find(name)
        if update_docs:  # before a long run: the page and its markers are there
            reproductions.check_page(name)
    except UserError as exc:
        _fail(exc)
    runs = rep.DEFAULT_RUNS if runs is None else runs
    seed = rep.DEFAULT_SEED if seed is None else seed
    if run_index is not None:
        try:
            click.echo(rep.rerun(case or rep.DEFAULT_CASE, int(run_index), int(runs), int(seed)))
        except UserError as exc:
            _fail(exc)
        return
    out = out or Path("out") / "reproduce" / name
    out.mkdir(parents=True, exist_ok=True)
    try:
        block = rep.reproduce(out, runs, seed)
    except UserError as exc:
        _fail(exc)
    (out / "tables.md").write_text(block)
    click.echo(block)
    click.echo(f"wrote {out / 'tables.md'} and the plots in {out}")
    if update_docs:
        try:
            click.echo(f"updated the {name} tables in {reproductions.publish(block, name)}")
        except UserError as exc:
            _fail(exc)


if __name__ == "__main__":  # pragma: no cover
    main()
