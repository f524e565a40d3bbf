"""Command line: ``ins-cosim run | check | fmus``.

A user's mistake (bad scenario, missing FMU, failing block) prints one message naming
the file, key, block or variable, and exits non-zero without a traceback:
3 for bad input, 4 for a run that stopped (its partial results are still written).
"""

from __future__ import annotations

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


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
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
def run(scenario: Path, out: Path, fmu_dir: Path | None, stop: str | None, plot: bool) -> None:
    """Run SCENARIO once and write its results to --out."""
    from cosim import Master
    from cosim.scenario import _seconds, load_scenario

    try:
        sc = load_scenario(scenario)
        if fmu_dir is not None:
            sc.use_fmus(fmu_dir)
        if stop is not None:
            sc.settings.stop = _seconds(stop, str(scenario), "--stop")
        system, meta = sc.build()
        master = Master(system, sc.settings, meta)
        n_blocks = len(system.blocks)
        click.echo(
            f"running '{sc.name}': {n_blocks} blocks, {sc.settings.n_steps} steps of "
            f"{sc.settings.step:g} s ({sc.settings.coupling})"
        )
        try:
            result = master.run()
        finally:
            master.terminate()
    except SimulationError as exc:
        click.echo(f"error: {exc}", err=True)
        if exc.result is not None:
            csv, _ = exc.result.save(out)
            click.echo(f"results recorded up to the failure are in {csv}", err=True)
        sys.exit(exc.exit_code)
    except UserError as exc:
        _fail(exc)
    csv, meta_file = result.save(out)
    click.echo(f"wrote {csv} ({len(result.data)} rows) and {meta_file}")
    if plot:
        from cosim.plots import plot_result

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
    """Validate SCENARIO (blocks, parameters, units, connections) without running it."""
    from cosim.master import Master
    from cosim.scenario import load_scenario

    try:
        sc = load_scenario(scenario)
        if fmu_dir is not None:
            sc.use_fmus(fmu_dir)
        system, meta = sc.build()
        try:
            master = Master(system, sc.settings, meta)
            master._warn_loops()
        finally:
            for host in system.blocks.values():
                host.terminate()
    except UserError as exc:
        _fail(exc)
    click.echo(
        f"{scenario}: OK - {len(system.blocks)} blocks, {len(system.connections)} scalar "
        f"connections, {sc.settings.n_steps} steps; stepping order: {' -> '.join(master.order)}"
    )


@main.command()
@click.option(
    "--dir",
    "fmu_dir",
    type=click.Path(path_type=Path),
    default=DEFAULT_FMU_DIR,
    show_default=True,
    help="Folder of FMUs.",
)
@click.option("--build", is_flag=True, help="First build every model in models/ into --dir.")
def fmus(fmu_dir: Path, build: bool) -> None:
    """List and validate (fmpy validate) the FMUs in --dir."""
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    from cosim.blocks import _sha256

    if build:
        from cosim.packaging import build_all

        for path in build_all(fmu_dir):
            click.echo(f"built {path}")
    files = sorted(Path(fmu_dir).glob("*.fmu"))
    if not files:
        click.echo(f"error: no FMUs in {fmu_dir}; run `make fmus` first", err=True)
        sys.exit(3)
    bad = 0
    click.echo(f"{'FMU':<28} {'FMI':<4} {'GUID':<37} {'sha256':<13} problems")
    for f in files:
        problems = validate_fmu(str(f))
        md = read_model_description(str(f), validate=False)
        bad += bool(problems)
        click.echo(
            f"{f.name:<28} {md.fmiVersion:<4} {md.guid:<37} {_sha256(f)[:12]:<13} {len(problems)}"
        )
        for p in problems:
            click.echo(f"    {p}")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":  # pragma: no cover
    main()
