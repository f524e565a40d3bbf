"""The one seed rule of every campaign, and stratified (Latin hypercube) draws.

Seeds of run ``i`` of a campaign with seed ``S`` (docs/verification.md)::

    state = SeedSequence(S).spawn(runs)[i].generate_state(len(names), uint32)
    seed of names[j] in run i = int(state[j] >> 1)          # 0 .. 2**31 - 1, an FMI Integer

``names`` lists every block with an Integer ``seed`` parameter, in file order; a
reproduction may append streams of its own after them (e.g. a fourth word named ``truth``
for a truth it draws itself). The words of ``generate_state`` do not depend on how many
are asked for, so appending a name never changes the seeds before it, and
``SeedSequence(S, spawn_key=(i,))`` is the ``i``-th spawned child for any ``runs > i``,
so a run's seeds do not depend on the number of runs either.

Stratified draws (``[campaign] stratify``): a parameter ``block.name`` with a sibling
``block.name_sigma`` (the turn-on sigma the block would draw ``name`` with from its own
seed) is drawn by the campaign instead: run ``i`` takes ``name = name_file + name_sigma *
z[i]`` and ``name_sigma = 0``, where ``z`` is a Latin-hypercube design of standard
normal draws over all stratified components (:func:`latin_hypercube_normal`, one column
per vector component in the order of the list).

The design (:func:`design_batches`) is a list of batch ends ``n_1 < n_2 < ... < n_K``:
batch ``j`` (0-based), runs ``n_{j-1} .. n_j - 1`` (``n_{-1} = 0``), is its own Latin
hypercube of ``n_j - n_{j-1}`` runs from stream ``j`` of the campaign seed. A fixed
campaign of ``N`` runs is the one batch ``(N,)``: stream 0 over all its runs. A campaign
of ``verify --until-decided`` has one batch per look (its planned looks, fixed before the
first run), so its first look is exactly the fixed campaign of ``n_1`` runs and each later
batch is a hypercube of its own, independent of the others (another stream). Every run is
marginally ``N(0, I)`` in both; within a batch the runs are not independent (one per
stratum), between batches they are. What that does to the confidence bounds, which assume
independent runs: :mod:`cosim.verify.sequential`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: uint32 >> 1: seeds fit an FMI Integer (int32), 0 .. 2**31 - 1.
SEED_SHIFT = 1
#: The rule in one line, recorded in every campaign's provenance.
SEED_RULE = (
    "seeds of run i = SeedSequence(campaign seed).spawn(runs)[i]"
    ".generate_state(len(seeded_blocks), uint32) >> 1, in seeded_blocks order; "
    "blocks not randomized keep the seed of the scenario file"
)
#: The stratified design in one line, recorded with every stratified campaign.
STRATIFY_RULE = (
    "design = batch ends n_1 < ... < n_K (a fixed campaign: (runs,); --until-decided: its "
    "looks); batch j, runs n_{j-1} .. n_j - 1, is latin_hypercube_normal(n_j - n_{j-1}, "
    "components, campaign seed, stream=j); run i takes name = file value + name_sigma * "
    "z_i and name_sigma = 0"
)
#: Suffix of the parameter that holds a stratified parameter's sigma.
SIGMA_SUFFIX = "_sigma"


def run_seeds(campaign_seed: int, index: int, names: Sequence[str]) -> dict[str, int]:
    """Seeds of one run, one per name, from the campaign seed (the module's rule).

    Parameters
    ----------
    campaign_seed : int
        Non-negative campaign seed.
    index : int
        Run number, 0-based.
    names : sequence of str
        Every block with a ``seed`` parameter, in file order, optionally followed by
        further stream names.

    Returns
    -------
    dict
        Name -> seed in [0, 2**31 - 1].
    """
    child = np.random.SeedSequence(int(campaign_seed), spawn_key=(int(index),))
    state = child.generate_state(max(1, len(names)), dtype=np.uint32)
    return {b: int(s) >> SEED_SHIFT for b, s in zip(names, state, strict=False)}


def latin_hypercube_normal(runs: int, dims: int, campaign_seed: int, stream: int = 0) -> np.ndarray:
    """Standard normal draws for a campaign, stratified per dimension (Latin hypercube).

    Each column splits the probability axis into ``runs`` equal strata and puts exactly
    one run in each, at a uniform position inside it, in a random order; the draw is
    ``z = Phi^-1(u)``. Every run's row is still marginally ``N(0, I)``, but the campaign's
    sample moments are far closer to the population's than with independent draws: for
    30 runs the mean square of a column spreads by about +-9 % (1 sigma) instead of
    +-26 % (``sqrt(2 / 30)``).

    The generator is ``SeedSequence(campaign_seed, spawn_key=(2**63, stream))``: a
    two-element spawn key, never equal to a run's ``(index,)`` of :func:`run_seeds`.

    Parameters
    ----------
    runs : int
        Number of runs (strata per dimension), >= 1.
    dims : int
        Number of independent standard normal variables per run, >= 1.
    campaign_seed : int
        Non-negative campaign seed.
    stream : int
        Independent design number for the same campaign seed (>= 0).

    Returns
    -------
    ndarray, shape (runs, dims)
        Row ``i``: the draws of run ``i`` (dimensionless; scale by the sigmas).

    Raises
    ------
    ValueError
        ``runs`` or ``dims`` below 1, or a negative seed or stream.
    """
    if int(runs) < 1 or int(dims) < 1:
        raise ValueError(f"runs and dims: expected >= 1, got {runs} and {dims}")
    if int(campaign_seed) < 0 or int(stream) < 0:
        raise ValueError(f"campaign_seed, stream: expected >= 0, got {campaign_seed}, {stream}")
    from scipy.special import ndtri

    seq = np.random.SeedSequence(int(campaign_seed), spawn_key=(2**63, int(stream)))
    rng = np.random.default_rng(seq)
    n, d = int(runs), int(dims)
    strata = np.argsort(rng.random((d, n)), axis=1).T  # one permutation per column
    u = (strata + rng.random((n, d))) / n
    return ndtri(u)


@dataclass(frozen=True)
class Stratified:
    """One stratified parameter of a campaign.

    Attributes
    ----------
    block : str
        Block name.
    name : str
        Parameter name (a vector's base name, e.g. ``accel_bias`` for
        ``accel_bias[1..3]``).
    size : int
        Number of components (1 for a scalar).
    vector : bool
        True when the parameter is declared as ``name[1] .. name[size]``.
    """

    block: str
    name: str
    size: int
    vector: bool

    @property
    def components(self) -> list[str]:
        """Parameter names of the components (``name`` or ``name[1] .. name[size]``)."""
        if not self.vector:
            return [self.name]
        return [f"{self.name}[{k + 1}]" for k in range(self.size)]

    @property
    def sigma(self) -> str:
        """Name of the parameter that holds its sigma (set to 0 in a stratified run)."""
        return f"{self.name}{SIGMA_SUFFIX}"


def design_batches(design: int | Sequence[int]) -> tuple[int, ...]:
    """The batch ends of a stratified design (the module's rule).

    Parameters
    ----------
    design : int or sequence of int
        ``N``: one Latin hypercube over runs 0 .. N - 1 (a fixed campaign of ``N`` runs);
        increasing run counts ``n_1 < ... < n_K``: one hypercube per batch (the looks of
        ``verify --until-decided``).

    Returns
    -------
    tuple of int
        ``(n_1, ..., n_K)``; ``(N,)`` for an int.

    Raises
    ------
    ValueError
        Not increasing, or a count below 1.
    """
    ends = (int(design),) if isinstance(design, int | np.integer) else tuple(int(n) for n in design)
    if not ends or ends[0] < 1 or any(b <= a for a, b in zip(ends, ends[1:], strict=False)):
        raise ValueError(f"a stratified design is increasing run counts >= 1, got {design!r}")
    return ends


def batch_of(index: int, design: int | Sequence[int]) -> tuple[int, int, int]:
    """The batch of a design that holds run ``index``.

    Parameters
    ----------
    index : int
        Run number, 0-based, below the design's last batch end.
    design : int or sequence of int
        As :func:`design_batches`.

    Returns
    -------
    (int, int, int)
        ``(j, start, size)``: batch number (the stream of its hypercube), its first run
        and its number of runs.

    Raises
    ------
    ValueError
        ``index`` outside ``0 .. n_K - 1``.
    """
    ends = design_batches(design)
    i = int(index)
    if not 0 <= i < ends[-1]:
        raise ValueError(f"run {index} is outside the stratified design of {ends[-1]} runs")
    j = int(np.searchsorted(ends, i, side="right"))
    start = ends[j - 1] if j > 0 else 0
    return j, start, ends[j] - start


def design_draws(design: int | Sequence[int], dims: int, campaign_seed: int) -> np.ndarray:
    """All standard normal draws of a stratified design, run by run.

    Parameters
    ----------
    design : int or sequence of int
        As :func:`design_batches`.
    dims : int
        Stratified components per run, >= 1.
    campaign_seed : int
        Campaign seed.

    Returns
    -------
    ndarray, shape (n_K, dims)
        Rows ``n_{j-1} .. n_j - 1``: ``latin_hypercube_normal(n_j - n_{j-1}, dims,
        campaign_seed, stream=j)`` (dimensionless).
    """
    ends = design_batches(design)
    starts = (0, *ends[:-1])
    return np.vstack(
        [
            latin_hypercube_normal(b - a, dims, campaign_seed, stream=j)
            for j, (a, b) in enumerate(zip(starts, ends, strict=True))
        ]
    )


def stratified_draws(
    stratify: Sequence[Stratified],
    runs: int | Sequence[int],
    campaign_seed: int,
    index: int,
) -> tuple[tuple[str, str, tuple[float, ...]], ...]:
    """The standard normal draws of run ``index`` for each stratified parameter.

    Parameters
    ----------
    stratify : sequence of Stratified
        The campaign's stratified parameters, in the order of ``[campaign] stratify``.
    runs : int or sequence of int
        The design (:func:`design_batches`): a fixed campaign's run count (one hypercube,
        the strata per component), or the batch ends of ``verify --until-decided`` (one
        hypercube per look).
    campaign_seed : int
        Campaign seed.
    index : int
        Run number, below the design's last batch end.

    Returns
    -------
    tuple of (str, str, tuple of float)
        ``(block, name, z)`` per parameter, ``z`` of length ``size`` (dimensionless);
        empty when nothing is stratified.

    Raises
    ------
    ValueError
        ``index`` outside the design, or a design that is not increasing.
    """
    if not stratify:
        return ()
    j, start, size = batch_of(index, runs)
    dims = sum(s.size for s in stratify)
    z = latin_hypercube_normal(size, dims, int(campaign_seed), stream=j)[int(index) - start]
    out, k = [], 0
    for s in stratify:
        out.append((s.block, s.name, tuple(float(v) for v in z[k : k + s.size])))
        k += s.size
    return tuple(out)
