"""Run an SSP archive in fmpy (a third master, beside ins-cosim and libcosim).

fmpy ships an SSP reader (``fmpy.ssp.ssd.read_ssd``, which validates the ``.ssd``
against the SSP 1.0 schemas) and a small fixed-step simulator
(``fmpy.ssp.simulation.simulate_ssp``). That simulator, as of fmpy 0.3, differs from the
coupling rule of ins-cosim and libcosim in four ways that change the numbers:

1. it sets no parameter values of the archive itself (only a ``parameter_set`` passed by
   the caller, with names ``Component.variable``);
2. it applies no ``ssc:LinearTransformation`` (it looks for the element in the ``ssd``
   namespace and never uses what it finds), neither factor nor offset;
3. it initialises every FMU without setting its connected inputs, and feeds 0.0 (not the
   sources' values at t0) to every input in the first step;
4. it advances time by adding the step (``time += step_size``), so ``t_n`` drifts from
   ``t0 + n h`` by roundings and the loop may take one step more; a row labelled ``t_n``
   holds the values at ``t_{n+1}``.

:func:`run_fmpy_ssp` therefore drives fmpy's own pieces (``read_ssd`` for the structure
and parameter sets, fmpy's ``FMU2Slave`` for each component, ``fmpy.ssp.simulation``'s
``set_value`` / ``get_value`` for the exchange) with the Jacobi rule of
docs/concepts.md: parameters and the sources' start values (0.0 for an output without one)
set before initialisation, then in each macro step every component reads the outputs
of the end of the previous step, steps from ``t_n = t0 + n h`` by ``t_{n+1} - t_n``,
and the connections are copied (``factor * value + offset`` of the transformation)
after all stepped. It runs flat archives of components with their own parameter sets
(what ``export-ssp`` writes, also from an imported archive with sub-systems, signal
dictionaries or parameter mappings: those come back flattened and applied); fmpy's
reader itself does not resolve them.
It imports nothing of ins-cosim's master, so the comparison is between two independent
implementations of the same rule.
"""

from __future__ import annotations

import shutil
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

__all__ = ["run_fmpy_ssp"]

_SSD = "{http://ssp-standard.org/SSP1/SystemStructureDescription}"
_SSC = "{http://ssp-standard.org/SSP1/SystemStructureCommon}"


def _factors(ssp: Path) -> dict[tuple[str, str, str, str], tuple[float, float]]:
    """(start element, start connector, end element, end connector) -> (factor, offset)."""
    with zipfile.ZipFile(ssp) as zf:
        root = ET.fromstring(zf.read("SystemStructure.ssd"))
    out = {}
    for c in root.iter(f"{_SSD}Connection"):
        key = (
            c.get("startElement", ""),
            c.get("startConnector", ""),
            c.get("endElement", ""),
            c.get("endConnector", ""),
        )
        t = c.find(f"{_SSC}LinearTransformation")
        factor, offset = 1.0, 0.0
        if t is not None:
            factor, offset = float(t.get("factor", 1.0)), float(t.get("offset", 0.0))
        out[key] = (factor, offset)
    return out


def _typed(variable: Any, text: str) -> Any:
    if variable.type == "Real":
        return float(text)
    if variable.type == "Enumeration" and variable.declaredType is not None:
        items = {item.name: int(item.value) for item in variable.declaredType.items}
        if text in items:
            return items[text]
    if variable.type in ("Integer", "Enumeration"):
        return int(text)
    if variable.type == "Boolean":
        return text in ("true", "1")
    return text


def run_fmpy_ssp(
    ssp_path: str | Path,
    step: float,
    stop: float,
    observe: Sequence[tuple[str, str]],
    start: float = 0.0,
) -> np.ndarray:
    """Run an SSP archive of FMI 2 co-simulation FMUs with fmpy, Jacobi coupling.

    Parameters
    ----------
    ssp_path : str or Path
        The ``.ssp`` archive (a flat system of FMU components).
    step : float
        Macro step h [s].
    stop : float
        Stop time [s]; ``(stop - start) / step`` must be a whole number.
    observe : sequence of (str, str)
        ``(component, variable)`` pairs to record (Real, Integer or Boolean), FMU names.
    start : float, optional
        Start time t0 [s], default 0.

    Returns
    -------
    numpy.ndarray
        Structured array of ``n + 1`` rows (``time`` then ``"component.variable"``):
        row 0 after initialisation at t0, row k at ``t0 + k h``.

    Raises
    ------
    ValueError
        A time grid that is not whole steps, a parameter with a unit (this driver applies
        values as they stand), or an unknown variable.
    """
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.ssp.simulation import get_value, set_value
    from fmpy.ssp.ssd import find_components, read_ssd

    ssp = Path(ssp_path)
    n_steps = round((stop - start) / step)
    if n_steps < 1 or abs(start + n_steps * step - stop) > 1e-9 * max(1.0, abs(stop)):
        raise ValueError(f"stop - start = {stop - start!r} s is not whole steps of {step!r} s")
    ssd = read_ssd(str(ssp))  # validates against the SSP 1.0 schema
    components = find_components(ssd.system)
    factors = _factors(ssp)
    unzipped = Path(extract(str(ssp)))
    into: dict[str, list[tuple[str, str, str, float, float]]] = {c.name: [] for c in components}
    for (se, sc, ee, ec), (factor, offset) in factors.items():
        into[ee].append((ec, se, sc, factor, offset))
    started = []
    try:
        for comp in components:
            fmu_file = unzipped / comp.source
            md = read_model_description(str(fmu_file), validate=False)
            comp.variables = {v.name: v for v in md.modelVariables}
            comp.unzipdir = extract(str(fmu_file))
            comp.fmu = FMU2Slave(
                guid=md.guid,
                unzipDirectory=comp.unzipdir,
                modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName=comp.name,
            )
            comp.fmu.instantiate()
            started.append(comp)
            comp.fmu.setupExperiment(startTime=start)
            for binding in comp.parameterBindings:
                for pset in binding.parameterValues:
                    for p in pset.parameters:
                        if getattr(p, "unit", None):
                            raise ValueError(f"{comp.name}.{p.name}: a parameter unit")
                        variable = comp.variables[p.name]
                        _set(comp, variable, _typed(variable, p.value))
        by_name = {c.name: c for c in components}
        for comp in components:  # inputs from the sources' start values (0.0 if none)
            for ec, se, sc, factor, offset in into[comp.name]:
                src = by_name[se].variables[sc]
                value = _typed(src, src.start) if src.start is not None else 0.0
                set_value(comp, ec, _transformed(value, factor, offset))
            comp.fmu.enterInitializationMode()
            comp.fmu.exitInitializationMode()
        outputs = {
            (c.name, v.name): get_value(c, v.name)
            for c in components
            for v in c.variables.values()
            if v.causality == "output" and v.type in ("Real", "Integer", "Boolean", "Enumeration")
        }
        names = ["time"] + [f"{b}.{v}" for b, v in observe]
        data = np.zeros(n_steps + 1, dtype=[(n, "f8") for n in names])

        def record(row: int, t: float) -> None:
            data[row]["time"] = t
            for b, v in observe:
                data[row][f"{b}.{v}"] = float(outputs[(b, v)])

        record(0, start)
        for n in range(n_steps):
            t_n, t_next = start + n * step, start + (n + 1) * step
            snapshot = dict(outputs)
            for comp in components:
                for ec, se, sc, factor, offset in into[comp.name]:
                    set_value(comp, ec, _transformed(snapshot[(se, sc)], factor, offset))
                comp.fmu.doStep(currentCommunicationPoint=t_n, communicationStepSize=t_next - t_n)
            for key in outputs:
                outputs[key] = get_value(by_name[key[0]], key[1])
            record(n + 1, t_next)
        return data
    finally:
        for comp in started:
            try:
                comp.fmu.terminate()
                comp.fmu.freeInstance()
            except Exception:  # noqa: S110 - cleanup after a failure must not mask it
                pass
            shutil.rmtree(comp.unzipdir, ignore_errors=True)
        shutil.rmtree(unzipped, ignore_errors=True)


def _transformed(value: Any, factor: float, offset: float) -> Any:
    """``factor * value + offset``; a value without a transformation passes as it is
    (an Integer or Boolean link keeps its type)."""
    if factor == 1.0 and offset == 0.0:
        return value
    if offset == 0.0:
        return factor * value
    return factor * value + offset


def _set(comp: Any, variable: Any, value: Any) -> None:
    """Set one parameter with its FMI type (fmpy's set_value reads 'false' as true)."""
    vr = [variable.valueReference]
    if variable.type == "Boolean":
        comp.fmu.setBoolean(vr, [bool(value)])
    elif variable.type == "String":
        comp.fmu.setString(vr, [str(value)])
    else:
        from fmpy.ssp.simulation import set_value

        set_value(comp, variable.name, value)
