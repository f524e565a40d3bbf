"""The registry: truth models by class name, everything else through entry points.

The extension point a user's package uses (docs/extending.md, "Adding your own model or filter"):
a test writes a toy alignment filter into a package of its own in ``tmp_path``, with the
``.dist-info`` metadata an installer would write, and runs it in a scenario against a
built-in truth model. Its output is compared with the closed form it must follow.
"""

from __future__ import annotations

import importlib
import inspect
import math
import pkgutil
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim import models, provenance, registry
from cosim.errors import ScenarioError
from cosim.models.block import Block
from cosim.models.constants import ARCMIN
from cosim.scenario import load_scenario
from cosim.verify.campaign import software_versions

ROOT = Path(__file__).resolve().parents[2]

# A toy alignment filter as a user would write it in a package of their own: a scalar
# Kalman filter (the project's estimator) of a constant angle read by a noisy sensor.
TOY_FILTER = '''
"""Toy alignment filter: the constant angle a sensor reads, by a scalar Kalman filter."""

import math

from cosim.estimation import KalmanFilter
from cosim.models.block import Block, input_, output, parameter


class ToyFilter(Block):
    """Scalar Kalman filter of a constant angle measured once per step with white noise."""

    variables = (
        parameter("sigma0", 0.01, "rad", "prior 1-sigma of the angle (prior mean 0)"),
        parameter("sigma_z", 0.001, "rad", "1-sigma noise of one measurement"),
        input_("z", 0.0, "rad", "measured angle"),
        output("estimate", 0.0, "rad", "estimated angle"),
        output("sigma", 0.0, "rad", "1-sigma of the estimate"),
    )

    def initialize(self):
        self._kf = KalmanFilter(dim_x=1, dim_z=1)
        self._kf.P = self.sigma0**2
        self._kf.H = [[1.0]]
        self._kf.R = self.sigma_z**2
        self.estimate, self.sigma = 0.0, self.sigma0

    def step(self, t, h):
        self._kf.predict()
        self._kf.update(self.z)
        self.estimate = float(self._kf.x[0])
        self.sigma = math.sqrt(self._kf.P[0, 0])
'''

# The sensor reads u + bias plus white noise of density N: per sample N / sqrt(h)
# = 0.01 arcmin sqrt(s) / sqrt(10 ms) = 0.1 arcmin, the sigma_z the filter is told.
SCENARIO = """
connections = ["sensor.m -> align.z"]

[master]
step = "10 ms"
stop = "2 s"

[blocks.sensor]
model = "FirstOrderSensor"

[blocks.sensor.parameters]
u = "3 arcmin"
bias = "0.5 arcmin"
noise_density = "0.01 arcmin/sqrt(Hz)"
seed = 5

[blocks.align]
model = "{model}"
parameters = { sigma0 = "10 arcmin", sigma_z = "0.1 arcmin" }
"""


def write_distribution(
    folder: Path, name: str, version: str, entry_points: dict[str, str], modules: dict[str, str]
) -> None:
    """An installed distribution as an installer leaves it: modules and their dist-info.

    Parameters
    ----------
    folder : Path
        A folder that will be on ``sys.path`` (site-packages stand-in).
    name, version : str
        Distribution name and version (METADATA).
    entry_points : dict
        ``{name: "module:Class"}`` of the group :data:`cosim.registry.GROUP`.
    modules : dict
        ``{module name: source}`` of the top-level modules it installs.
    """
    for module, source in modules.items():
        (folder / f"{module}.py").write_text(textwrap.dedent(source))
    info = folder / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    lines = [f"[{registry.GROUP}]"] + [f"{k} = {v}" for k, v in entry_points.items()]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """A folder on ``sys.path`` for distributions of the test; their modules are forgotten after."""
    folder = tmp_path / "site"
    folder.mkdir()
    monkeypatch.syspath_prepend(str(folder))
    before = set(sys.modules)
    yield folder
    for name in set(sys.modules) - before:
        if name.startswith("toy_"):
            del sys.modules[name]
    importlib.invalidate_caches()


def toy_package(site: Path) -> None:
    """The toy filter's distribution, ``toy-filters 0.1``."""
    write_distribution(
        site,
        "toy-filters",
        "0.1",
        {"ToyFilter": "toy_filters:ToyFilter"},
        {"toy_filters": TOY_FILTER},
    )
    importlib.invalidate_caches()


def toy_scenario(tmp_path: Path, model: str = "ToyFilter") -> Path:
    path = tmp_path / "toy.toml"
    path.write_text(SCENARIO.replace("{model}", model))
    return path


def expected_estimates(m: np.ndarray, sigma0: float, sigma_z: float) -> tuple[np.ndarray, ...]:
    """The Kalman filter of a constant in information form: prior N(0, sigma0^2), then the
    measurements m[1], m[2], ... (m[0] is the value at t0, before the first step)."""
    k = np.arange(len(m))
    information = 1.0 / sigma0**2 + k / sigma_z**2
    sums = np.concatenate([[0.0], np.cumsum(m[1:])])
    return sums / sigma_z**2 / information, 1.0 / np.sqrt(information)


def test_a_users_filter_package_runs_in_a_scenario(site: Path, tmp_path: Path) -> None:
    toy_package(site)
    result = cosim.run(toy_scenario(tmp_path))
    m = result["sensor.m"]
    estimate, sigma = expected_estimates(m, 10 * ARCMIN, 0.1 * ARCMIN)
    np.testing.assert_allclose(result["align.estimate"], estimate, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(result["align.sigma"], sigma, rtol=1e-9)
    truth = 3.5 * ARCMIN  # u + bias, what the sensor reads without noise
    assert abs(result["align.estimate"][-1] - truth) < 3 * result["align.sigma"][-1]
    assert result["align.sigma"][-1] == pytest.approx(0.1 * ARCMIN / math.sqrt(200), rel=1e-3)
    meta = result.metadata["blocks"]["align"]
    assert meta["kind"] == "model" and meta["source"] == "toy_filters.ToyFilter"


def test_the_docs_show_the_filter_this_test_runs() -> None:
    text = (ROOT / "docs" / "extending.md").read_text(encoding="utf-8")
    section = text.split("# Adding your own model or filter", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    path_comment, _, source = code.partition("\n")
    assert path_comment.startswith("# ") and source.strip() == TOY_FILTER.strip()


def test_a_users_filter_runs_from_the_command_line(cli, tmp_path: Path) -> None:
    # the CLI runs in tmp_path, whose folder is on its sys.path (python -m): put it there
    toy_package(tmp_path)
    res = cli("run", toy_scenario(tmp_path), "--out", tmp_path / "out", "--no-plot")
    assert res.code == 0, res.err
    header = (tmp_path / "out" / "results.csv").read_text().splitlines()[0]
    assert "align.estimate" in header and "align.sigma" in header


def test_names_lists_truth_models_then_entry_points_without_importing_them(site: Path) -> None:
    toy_package(site)
    known = registry.names()
    truth = list(models.truth_models())
    assert known[: len(truth)] == truth
    assert {"ToyFilter", "SinsStaticAlignment", "TransferAlignment"} <= set(known[len(truth) :])
    assert "toy_filters" not in sys.modules
    assert registry.find_block("ToyFilter").__module__ == "toy_filters"


BROKEN = {
    "BrokenFilter": "toy_broken:BrokenFilter",
    "MissingClass": "toy_filters:NoSuchFilter",
    "NotABlock": "toy_filters:math",
}


def test_a_broken_entry_point_fails_only_when_asked_for(site: Path, tmp_path: Path) -> None:
    toy_package(site)
    write_distribution(
        site,
        "toy-broken",
        "0.2",
        BROKEN,
        {"toy_broken": "import toy_dependency_not_installed\n"},
    )
    importlib.invalidate_caches()
    # every other name still resolves, and a scenario of them still runs
    assert set(BROKEN) <= set(registry.names())
    assert registry.find_block("GaussMarkov2") is models.truth_models()["GaussMarkov2"]
    assert registry.find_block("ToyFilter").__name__ == "ToyFilter"
    assert cosim.run(toy_scenario(tmp_path), stop=0.1).status == "completed"
    with pytest.raises(ScenarioError) as info:
        registry.find_block("BrokenFilter")
    message = str(info.value)
    for part in (
        "'BrokenFilter = toy_broken:BrokenFilter'",
        "distribution 'toy-broken 0.2'",
        str(site),
        "ModuleNotFoundError",
        "toy_dependency_not_installed",
    ):
        assert part in message
    with pytest.raises(ScenarioError, match="MissingClass = toy_filters:NoSuchFilter.*Attr"):
        registry.find_block("MissingClass")
    with pytest.raises(ScenarioError, match="not a subclass of cosim.models.block.Block"):
        registry.find_block("NotABlock")
    # in a scenario: the file and the block's key
    scenario = load_scenario(toy_scenario(tmp_path, "BrokenFilter"))
    with pytest.raises(ScenarioError) as info:
        scenario.build()
    assert info.value.key == "blocks.align.model" and info.value.file == str(scenario.path)
    assert "toy_dependency_not_installed" in info.value.message


def test_an_unknown_name_says_what_is_known(site: Path) -> None:
    toy_package(site)
    with pytest.raises(ScenarioError) as info:
        registry.find_block("ToyFiltre")
    message = info.value.message
    assert "unknown model 'ToyFiltre'. Did you mean 'ToyFilter'?" in message
    assert "GaussMarkov2" in message and "SinsStaticAlignment" in message
    assert registry.GROUP in message


def test_a_name_claimed_twice_is_refused_when_used(site: Path) -> None:
    toy_package(site)
    write_distribution(
        site,
        "toy-clash",
        "1.0",
        {"ToyFilter": "toy_clash:ToyFilter", "GaussMarkov2": "toy_clash:ToyFilter"},
        {"toy_clash": "from toy_filters import ToyFilter\n"},
    )
    importlib.invalidate_caches()
    for name in ("ToyFilter", "GaussMarkov2"):
        with pytest.raises(ScenarioError, match=f"'{name}' is claimed more than once"):
            registry.find_block(name)
    assert registry.find_block("FirstOrderSensor").__name__ == "FirstOrderSensor"


def _alignment_blocks() -> dict[str, type[Block]]:
    """Every public Block class defined in a module of cosim.alignment."""
    import cosim.alignment as package

    found: dict[str, type[Block]] = {}
    for info in pkgutil.walk_packages(package.__path__, prefix="cosim.alignment."):
        module = importlib.import_module(info.name)
        for name, obj in inspect.getmembers(module, inspect.isclass):
            if issubclass(obj, Block) and obj.__module__ == module.__name__:
                if not name.startswith("_"):
                    found[name] = obj
    return found


def test_every_alignment_filter_is_registered_under_its_class_name() -> None:
    blocks = _alignment_blocks()
    assert {"SinsStaticAlignment", "TransferAlignment", "HrgTwoPositionAlignment"} <= set(blocks)
    ours = {
        name: regs
        for name, regs in registry.entry_points().items()
        if any("'ins-cosim " in r.distribution for r in regs)
    }
    from cosim.sensors.master_replay import MasterInsLogReplay  # the log replays (issue 17)
    from cosim.sensors.replay import ImuLogReplay

    blocks["ImuLogReplay"] = ImuLogReplay
    blocks["MasterInsLogReplay"] = MasterInsLogReplay
    assert set(ours) == set(blocks)
    for name, cls in blocks.items():
        assert registry.find_block(name) is cls


def test_truth_models_are_what_make_fmus_packs_and_no_entry_point_shadows_them() -> None:
    truth = registry.truth_models()
    assert truth == models.truth_models()
    assert not set(truth) & set(registry.entry_points())
    assert all(registry.is_truth_model(name) for name in truth)
    assert not registry.is_truth_model("SinsStaticAlignment")


def test_use_fmus_swaps_truth_models_only(tmp_path: Path) -> None:
    path = tmp_path / "mixed.toml"
    path.write_text(
        "[master]\nstep = 0.1\nstop = 1.0\n"
        "[blocks.base]\nmodel = 'StationaryBase'\n"
        "[blocks.align]\nmodel = 'SinsStaticAlignment'\n"
    )
    scenario = load_scenario(path)
    scenario.use_fmus(tmp_path / "fmus")
    assert scenario.blocks["base"].kind == "fmu"
    fmu = (tmp_path / "fmus" / "StationaryBase.fmu").resolve()
    assert scenario.blocks["base"].source == str(fmu)
    assert scenario.blocks["align"].kind == "model"
    assert scenario.blocks["align"].source == "SinsStaticAlignment"


def test_name_and_version_from_the_metadata_header_equal_the_full_parse(
    site: Path,
) -> None:
    # every distribution of this environment (ins-cosim's METADATA carries the README as
    # its long description, a blank line and "Name:"-like lines included), plus one whose
    # metadata file is missing the version (the full parse is then what answers)
    from importlib import metadata

    dists = list(metadata.distributions())
    assert len(dists) > 10
    for dist in dists:
        assert provenance.name_and_version(dist) == (dist.metadata["Name"], dist.version)
    info = site / "odd-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: odd\n\nVersion: 9.9\n")
    odd = metadata.PathDistribution(info)
    assert provenance.name_and_version(odd) == (odd.metadata["Name"], odd.version)
    # the versions written into every result, read the same way
    software = provenance.versions()
    assert software["ins-cosim"] == metadata.version("ins-cosim")
    for package, version in software.items():
        if package not in ("python", "platform", "kernels"):
            assert version == metadata.version(package)
    # and a campaign's report: the same, plus the packages it uses (missing ones left out)
    report = software_versions()
    assert list(report)[: len(software)] == list(software)
    assert {"click", "tqdm"} <= set(report)
    for package, version in report.items():
        if package not in ("python", "platform", "kernels"):
            assert version == metadata.version(package)
    assert "no-such-dist" not in provenance.versions(("no-such-dist",))
