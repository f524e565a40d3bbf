"""A reference master for the typed-link tests: fmpy's FMU wrappers driven by the coupling rule.

Independent of ins-cosim's master, hosts and array handling (it reads the model
descriptions and calls fmpy's ``FMU2Slave`` / ``FMU3Slave`` itself): blocks step in the
given order, each from ``t_n = t0 + n h`` by ``h``; Gauss-Seidel sinks read the value
their source holds at that moment, Jacobi sinks the values all sources held at ``t_n``
(at initialisation: the sources' start values, 0 where none is declared). FMI 3 arrays
are got and set whole; an element is set by setting the whole array from a copy that
holds the other elements' last values. Widening links convert the value to the sink's
type (int -> float, Float32 -> Float64, narrower -> wider integer).
"""

from __future__ import annotations

import itertools
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

_FLOATS = {"Real", "Float64", "Float32"}


def _starts(v: Any, size: int) -> list[Any]:
    words = str(v.start).split() if v.start is not None else []
    if len(words) == 1:
        words *= size
    if len(words) != size:
        return [False if v.type == "Boolean" else 0] * size
    if v.type in _FLOATS:
        return [float(w) for w in words]
    if v.type == "Boolean":
        return [w in ("true", "1") for w in words]
    if v.type == "String":
        return words
    return [int(w) for w in words]


class Slave:
    """One FMU instance with get/set by scalar name (``x``, ``x[2]``, ``A[1,2]``)."""

    def __init__(self, name: str, path: Path) -> None:
        md = read_model_description(str(path))
        self.fmi2 = md.fmiVersion == "2.0"
        self.unzip = extract(str(path))
        cls = FMU2Slave if self.fmi2 else FMU3Slave
        self.fmu = cls(
            guid=md.guid,
            unzipDirectory=self.unzip,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        if self.fmi2:
            self.fmu.instantiate()
        else:
            self.fmu.instantiate(logMessage=lambda *args: None)
        self.vars: dict[str, tuple[int, str, int, int]] = {}  # vr, type, index, size
        self.shadow: dict[int, list[Any]] = {}
        self.types: dict[str, str] = {}
        self.starts: dict[str, Any] = {}  # None where the FMU declares no start value
        for v in md.modelVariables:
            shape = tuple(getattr(v, "shape", ()) or ())
            if not getattr(v, "dimensions", None):
                self.vars[v.name] = (v.valueReference, v.type, 0, 0)
                self.types[v.name] = v.type
                self.starts[v.name] = _starts(v, 1)[0] if v.start is not None else None
                continue
            size = math.prod(shape)
            self.shadow[v.valueReference] = _starts(v, size)
            for i, index in enumerate(itertools.product(*(range(1, n + 1) for n in shape))):
                element = f"{v.name}[{','.join(map(str, index))}]"
                self.vars[element] = (v.valueReference, v.type, i, size)
                self.types[element] = v.type
                self.starts[element] = self.shadow[v.valueReference][i] if v.start else None

    def _call(self, kind: str, vtype: str) -> Any:
        if self.fmi2:
            vtype = {"Enumeration": "Integer"}.get(vtype, vtype)
        else:
            vtype = {"Enumeration": "Int64"}.get(vtype, vtype)
        return getattr(self.fmu, f"{kind}{vtype}")

    def get(self, name: str) -> Any:
        vr, vtype, index, size = self.vars[name]
        get = self._call("get", vtype)
        if size:
            return get([vr], size)[index]
        return get([vr])[0]

    def set(self, name: str, value: Any) -> None:
        vr, vtype, index, size = self.vars[name]
        set_ = self._call("set", vtype)
        if size:
            self.shadow[vr][index] = value
            set_([vr], self.shadow[vr])
        else:
            set_([vr], [value])

    def convert(self, name: str, value: Any) -> Any:
        """A source value as this FMU's variable ``name`` takes it."""
        vtype = self.types[name]
        if isinstance(value, bytes):
            value = value.decode()
        if vtype in _FLOATS:
            return float(value)
        if vtype == "Boolean":
            return bool(value)
        if vtype == "String":
            return str(value)
        return int(value)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.unzip, ignore_errors=True)


def run_chain(
    fmus: dict[str, Path],
    parameters: dict[str, dict[str, Any]],
    links: list[tuple[str, str, str, str]],
    record: list[tuple[str, str]],
    step: float,
    stop: float,
    coupling: str,
) -> dict[str, np.ndarray]:
    """Run the FMUs in the order of ``fmus`` and record ``record`` after every macro step.

    Parameters
    ----------
    fmus : dict
        Block name -> FMU file, in stepping order.
    parameters : dict
        Block -> {scalar name: value} set before initialisation.
    links : list of (str, str, str, str)
        Scalar links (source block, output, sink block, input).
    record : list of (str, str)
        (block, scalar output) pairs to record.
    step, stop : float
        Macro step and stop time [s] (start 0).
    coupling : str
        ``"gauss-seidel"`` or ``"jacobi"``.

    Returns
    -------
    dict
        ``"block.var"`` -> float64 array (booleans 0/1) of ``stop / step + 1`` rows; text
        columns as object arrays of str.
    """
    slaves = {name: Slave(name, path) for name, path in fmus.items()}
    try:
        live: dict[tuple[str, str], Any] = {}
        for sb, sv, _db, _dv in links:
            start = slaves[sb].starts[sv]
            vtype = slaves[sb].types[sv]
            zero = 0.0 if vtype in _FLOATS else ("" if vtype == "String" else 0)
            live[(sb, sv)] = zero if start is None else start
        jacobi = coupling == "jacobi"
        rows: list[list[Any]] = []

        def publish(name: str) -> None:
            for key in live:
                if key[0] == name:
                    live[key] = slaves[name].get(key[1])

        def feed(name: str, table: dict[tuple[str, str], Any]) -> None:
            for sb, sv, db, dv in links:
                if db == name:
                    slaves[name].set(dv, slaves[name].convert(dv, table[(sb, sv)]))

        def write() -> None:
            row = []
            for b, v in record:
                x = slaves[b].get(v)
                row.append(x.decode() if isinstance(x, bytes) else x)
            rows.append(row)

        snapshot = dict(live)
        for name, slave in slaves.items():
            if slave.fmi2:
                slave.fmu.setupExperiment(startTime=0.0)
                for var, value in parameters.get(name, {}).items():
                    slave.set(var, value)
                slave.fmu.enterInitializationMode()
            else:
                for var, value in parameters.get(name, {}).items():
                    slave.set(var, value)
                slave.fmu.enterInitializationMode(startTime=0.0)
            feed(name, snapshot if jacobi else live)
            slave.fmu.exitInitializationMode()
            publish(name)
        write()
        n_steps = round(stop / step)
        for n in range(n_steps):
            snapshot = dict(live)
            t = n * step
            for name, slave in slaves.items():
                feed(name, snapshot if jacobi else live)
                slave.fmu.doStep(t, step)
                publish(name)
            write()
    finally:
        for slave in slaves.values():
            slave.close()
    out: dict[str, np.ndarray] = {}
    for i, (b, v) in enumerate(record):
        column = [r[i] for r in rows]
        if any(isinstance(x, str) for x in column):
            out[f"{b}.{v}"] = np.array(column, dtype=object)
        else:
            out[f"{b}.{v}"] = np.array([float(x) for x in column])
    return out
