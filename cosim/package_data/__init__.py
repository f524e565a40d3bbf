"""Where the files the commands read at run time are, in a checkout and in an installed wheel.

A wheel carries the role interface specs (``fmus/interfaces/*.toml`` of the repository) and
the shipped scenarios (``scenarios/*.toml``) as package data under this package
(``cosim/package_data/interfaces``, ``cosim/package_data/scenarios``; pyproject.toml maps the
folders). In a checkout (editable install) those subfolders do not exist here and the
repository's own folders are used, so an edited spec or scenario takes effect at once.
"""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent
#: The repository root when running from a checkout (``cosim/package_data/../..``).
CHECKOUT = HERE.parents[1]


def role_dir() -> Path:
    """The folder of the role interface specs (``<role>.toml``).

    Returns
    -------
    Path
        ``cosim/package_data/interfaces`` in an installed wheel, ``fmus/interfaces`` in a
        checkout.
    """
    installed = HERE / "interfaces"
    if installed.is_dir():
        return installed
    return CHECKOUT / "fmus" / "interfaces"


def scenario_dir() -> Path:
    """The folder of the shipped scenarios (``demo.toml``, ``sins_north_finding.toml``, ...).

    Returns
    -------
    Path
        ``cosim/package_data/scenarios`` in an installed wheel, ``scenarios`` in a checkout.
    """
    installed = HERE / "scenarios"
    if installed.is_dir():
        return installed
    return CHECKOUT / "scenarios"


def scenario_file(name: str) -> Path:
    """A shipped scenario by file name.

    Parameters
    ----------
    name : str
        File name, e.g. ``"sins_north_finding.toml"``.

    Returns
    -------
    Path
        Its path (see :func:`scenario_dir`).
    """
    return scenario_dir() / name
