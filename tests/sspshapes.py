"""SSP archives in the shapes other tools write, written by hand for the tests.

Each archive is a ``SystemStructure.ssd`` (plus ``.ssv`` / ``.ssm`` / ``.ssb`` files) in
the shapes of the SSP 1.0 and 2.0 standards' examples and of what OMSimulator, libcosim
and Ecos's sspgen write and read, around four FMUs: the C fixtures ``Decay`` (``x`` with
``dx/dt = -k x``, the Integer output ``n_int``) and ``Echo`` (a parameter and an input of
every FMI 2 type, echoed: ``y_real = p_real + u_real`` ...), compiled in the test run, and
the project's ``GaussMarkov2`` and ``FirstOrderSensor`` (``make fmus``).

:data:`ARCHIVES` maps a name to ``(ssd, {member: text})``. All run 10 macro steps of
0.1 s under Jacobi coupling (the archives state no coupling).
"""

from __future__ import annotations

import zipfile
from pathlib import Path

HEAD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="{version}" name="{name}"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
    xmlns:ssb="http://ssp-standard.org/SSP1/SystemStructureSignalDictionary"
    xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations"
    generationTool="written by hand (ins-cosim tests)">
"""
TAIL = """  <ssd:DefaultExperiment startTime="0" stopTime="1">
    <ssd:Annotations>
      <ssc:Annotation type="com.opensimulationplatform">
        <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="0.1"/></osp:Algorithm>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""
FMU = 'type="application/x-fmu-sharedlibrary" implementation="CoSimulation"'


def pset(name: str, body: str) -> str:
    """An inline parameter binding holding ``body`` (``ssv:Parameter`` elements)."""
    return f"""<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
<ssv:ParameterSet version="1.0" name="{name}"><ssv:Parameters>{body}</ssv:Parameters>
</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"""


def real(name: str, value: float, unit: str = "", kind: str = "Real") -> str:
    """One ``ssv:Parameter`` with a Real value (and unit)."""
    u = f' unit="{unit}"' if unit else ""
    return f'<ssv:Parameter name="{name}"><ssv:{kind} value="{value!r}"{u}/></ssv:Parameter>'


def integer(name: str, value: int, kind: str = "Integer") -> str:
    """One ``ssv:Parameter`` with an Integer value."""
    return f'<ssv:Parameter name="{name}"><ssv:{kind} value="{value}"/></ssv:Parameter>'


def conn(a: str, b: str, extra: str = "", inner: str = "") -> str:
    """``ssd:Connection`` from ``a`` to ``b`` (``"element.connector"`` or ``".connector"``)."""
    (se, sc), (ee, ec) = a.split(".", 1), b.split(".", 1)
    start = f'startElement="{se}" ' if se else ""
    end = f'endElement="{ee}" ' if ee else ""
    body = f">{inner}</ssd:Connection>" if inner else "/>"
    return f'<ssd:Connection {start}startConnector="{sc}" {end}endConnector="{ec}"{extra}{body}'


def linear(factor: float, offset: float = 0.0) -> str:
    """An ``ssc:LinearTransformation``."""
    return f'<ssc:LinearTransformation factor="{factor!r}" offset="{offset!r}"/>'


def connector(name: str, kind: str, vtype: str = "Real", attrs: str = "") -> str:
    """One ``ssd:Connector``."""
    return f'<ssd:Connector name="{name}" kind="{kind}"><ssc:{vtype}{attrs}/></ssd:Connector>'


GAUSS_MARKOV_SET = pset("gm", real("tau", 0.5) + real("sigma", 0.01) + integer("seed", 7))

# 1. hierarchy: sub-systems two deep, connectors in and out, bindings at three levels
HIERARCHY = (
    HEAD.format(version="1.0", name="Hierarchy")
    + f"""<ssd:System name="Plant">
<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
<ssv:ParameterSet version="1.0" name="top"><ssv:Parameters>
{integer("deck.flex.seed", 7)}{real("deck.inner.d.k", 2.0)}
</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>
</ssd:ParameterBindings>
<ssd:Elements>
<ssd:System name="deck">
<ssd:Connectors>{connector("angle", "output")}{connector("decay", "output")}
{connector("cmd", "input")}</ssd:Connectors>
<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
<ssv:ParameterSet version="1.0" name="deck"><ssv:Parameters>
{real("flex.tau", 0.5)}{real("flex.sigma", 0.01)}{integer("flex.seed", 3)}
</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>
</ssd:ParameterBindings>
<ssd:Elements>
<ssd:Component name="flex" source="resources/GaussMarkov2.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output", attrs=' unit="rad"')}</ssd:Connectors>
{pset("flex-own", integer("seed", 1))}
</ssd:Component>
<ssd:System name="inner">
<ssd:Connectors>{connector("x_out", "output")}</ssd:Connectors>
<ssd:Elements>
<ssd:Component name="d" source="resources/Decay.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output")}</ssd:Connectors>
{pset("d", real("k", 0.5) + real("x0", 2.0))}
</ssd:Component>
</ssd:Elements>
<ssd:Connections>{conn("d.x", ".x_out")}</ssd:Connections>
</ssd:System>
<ssd:Component name="echo" source="resources/Echo.fmu" {FMU}>
<ssd:Connectors>{connector("u_real", "input")}{connector("y_real", "output")}</ssd:Connectors>
</ssd:Component>
</ssd:Elements>
<ssd:Connections>
{conn("flex.x", ".angle")}{conn("inner.x_out", ".decay")}{conn(".cmd", "echo.u_real")}
</ssd:Connections>
</ssd:System>
<ssd:Component name="sensor" source="resources/FirstOrderSensor.fmu" {FMU}>
<ssd:Connectors>{connector("u", "input")}{connector("y", "output")}</ssd:Connectors>
{pset("sensor", real("time_constant", 0.2))}
</ssd:Component>
<ssd:Component name="echo" source="resources/Echo.fmu" {FMU}>
<ssd:Connectors>{connector("u_real", "input")}{connector("y_real", "output")}</ssd:Connectors>
</ssd:Component>
</ssd:Elements>
<ssd:Connections>
{conn("deck.angle", "sensor.u", inner=linear(2.0, 0.001))}
{conn("deck.decay", "echo.u_real", inner=linear(-1.5))}
{conn("echo.y_real", "deck.cmd")}
{conn("sensor.y", ".out")}
</ssd:Connections>
</ssd:System>
"""
    + TAIL
).replace(
    '<ssd:System name="Plant">',
    '<ssd:System name="Plant">\n<ssd:Connectors>'
    + connector("out", "output")
    + "</ssd:Connectors>",
    1,
)

# 2. parameter mappings: an .ssm file (transformations of every kind) and one inline
SSM = """<?xml version="1.0" encoding="UTF-8"?>
<ssm:ParameterMapping version="1.0"
    xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssm:MappingEntry source="gain" target="p_real">
    <ssc:LinearTransformation factor="2" offset="1"/></ssm:MappingEntry>
  <ssm:MappingEntry source="count" target="p_int">
    <ssc:IntegerMappingTransformation><ssc:MapEntry source="5" target="50"/>
    </ssc:IntegerMappingTransformation></ssm:MappingEntry>
  <ssm:MappingEntry source="flag" target="p_bool">
    <ssc:BooleanMappingTransformation><ssc:MapEntry source="true" target="false"/>
    <ssc:MapEntry source="false" target="true"/></ssc:BooleanMappingTransformation>
  </ssm:MappingEntry>
  <ssm:MappingEntry source="level" target="u_enum">
    <ssc:EnumerationMappingTransformation><ssc:MapEntry source="HI" target="high"/>
    </ssc:EnumerationMappingTransformation></ssm:MappingEntry>
  <ssm:MappingEntry source="label" target="p_str"/>
</ssm:ParameterMapping>
"""
ECHO_SET = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet version="1.0" name="echo-vendor"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssv:Parameters>
    <ssv:Parameter name="gain"><ssv:Real value="0.25"/></ssv:Parameter>
    <ssv:Parameter name="count"><ssv:Integer value="5"/></ssv:Parameter>
    <ssv:Parameter name="flag"><ssv:Boolean value="true"/></ssv:Parameter>
    <ssv:Parameter name="level"><ssv:String value="HI"/></ssv:Parameter>
    <ssv:Parameter name="label"><ssv:String value="deck"/></ssv:Parameter>
  </ssv:Parameters>
</ssv:ParameterSet>
"""
MAPPING = (
    HEAD.format(version="1.0", name="Mapping")
    + f"""<ssd:System name="Mapped"><ssd:Elements>
<ssd:Component name="decay" source="resources/Decay.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output")}</ssd:Connectors>
<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
<ssv:ParameterSet version="1.0" name="decay"><ssv:Parameters>
{real("rate", 30.0, "1/min")}{real("start", 4.0)}
</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>
<ssd:ParameterMapping><ssm:ParameterMapping version="1.0">
<ssm:MappingEntry source="rate" target="k"/>
<ssm:MappingEntry source="start" target="x0" suppressUnitConversion="true"/>
</ssm:ParameterMapping></ssd:ParameterMapping>
</ssd:ParameterBinding></ssd:ParameterBindings>
</ssd:Component>
<ssd:Component name="echo" source="resources/Echo.fmu" {FMU}>
<ssd:Connectors>{connector("u_real", "input")}{connector("y_real", "output")}</ssd:Connectors>
<ssd:ParameterBindings><ssd:ParameterBinding source="resources/echo.ssv">
<ssd:ParameterMapping source="resources/echo.ssm"/>
</ssd:ParameterBinding></ssd:ParameterBindings>
</ssd:Component>
</ssd:Elements>
<ssd:Connections>{conn("decay.x", "echo.u_real")}</ssd:Connections>
</ssd:System>
"""
    + TAIL
)

# 3. .ssv with units: ssv:Units of the set, ssd:Units of the SSD, and units by name
SENSOR_SET = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet version="1.0" name="sensor-datasheet"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssv:Parameters>
    <ssv:Parameter name="time_constant"><ssv:Real value="150" unit="ms"/></ssv:Parameter>
    <ssv:Parameter name="bias"><ssv:Real value="3" unit="mrad"/></ssv:Parameter>
  </ssv:Parameters>
  <ssv:Units>
    <ssc:Unit name="mrad"><ssc:BaseUnit rad="1" factor="0.001"/></ssc:Unit>
  </ssv:Units>
</ssv:ParameterSet>
"""
UNITS = (
    HEAD.format(version="1.0", name="Units")
    + f"""<ssd:System name="Sensors"><ssd:Elements>
<ssd:Component name="flex" source="resources/GaussMarkov2.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output", attrs=' unit="rad"')}</ssd:Connectors>
{pset("gm", real("tau", 0.01, "min") + real("sigma", 0.5, "degree") + integer("seed", 7))}
</ssd:Component>
<ssd:Component name="sensor" source="resources/FirstOrderSensor.fmu" {FMU}>
<ssd:Connectors>{connector("u", "input", attrs=' unit="rad"')}{connector("y", "output")}
</ssd:Connectors>
<ssd:ParameterBindings><ssd:ParameterBinding source="resources/sensor.ssv"/>
</ssd:ParameterBindings>
</ssd:Component>
<ssd:Component name="decay" source="resources/Decay.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output")}</ssd:Connectors>
{pset("decay", real("k", 1.0, "1/h") + real("dt_int", 20.0, "ms"))}
</ssd:Component>
</ssd:Elements>
<ssd:Connections>{conn("flex.x", "sensor.u")}</ssd:Connections>
</ssd:System>
<ssd:Units>
<ssc:Unit name="rad"><ssc:BaseUnit rad="1"/></ssc:Unit>
<ssc:Unit name="degree"><ssc:BaseUnit rad="1" factor="0.017453292519943295"/></ssc:Unit>
</ssd:Units>
"""
    + TAIL
)

# 4. signal dictionaries: one inline, one in an .ssb file, read through two references
SSB = """<?xml version="1.0" encoding="UTF-8"?>
<ssb:SignalDictionary version="1.0"
    xmlns:ssb="http://ssp-standard.org/SSP1/SystemStructureSignalDictionary"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssb:DictionaryEntry name="decay"><ssc:Real/></ssb:DictionaryEntry>
  <ssb:DictionaryEntry name="steps"><ssc:Integer/></ssb:DictionaryEntry>
</ssb:SignalDictionary>
"""
DICTIONARY = (
    HEAD.format(version="1.0", name="Dictionary")
    + f"""<ssd:System name="Bus"><ssd:Elements>
<ssd:Component name="flex" source="resources/GaussMarkov2.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output")}</ssd:Connectors>{GAUSS_MARKOV_SET}
</ssd:Component>
<ssd:Component name="decay" source="resources/Decay.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output")}</ssd:Connectors>
</ssd:Component>
<ssd:SignalDictionaryReference name="busIn" dictionary="nav">
<ssd:Connectors>{connector("angle", "input")}</ssd:Connectors>
</ssd:SignalDictionaryReference>
<ssd:SignalDictionaryReference name="busOut" dictionary="nav">
<ssd:Connectors>{connector("angle", "output")}</ssd:Connectors>
</ssd:SignalDictionaryReference>
<ssd:SignalDictionaryReference name="plantIn" dictionary="plant">
<ssd:Connectors>{connector("decay", "input")}</ssd:Connectors>
</ssd:SignalDictionaryReference>
<ssd:SignalDictionaryReference name="plantOut" dictionary="plant">
<ssd:Connectors>{connector("decay", "output")}</ssd:Connectors>
</ssd:SignalDictionaryReference>
<ssd:Component name="sensor" source="resources/FirstOrderSensor.fmu" {FMU}>
<ssd:Connectors>{connector("u", "input")}{connector("y", "output")}</ssd:Connectors>
</ssd:Component>
<ssd:Component name="echo" source="resources/Echo.fmu" {FMU}>
<ssd:Connectors>{connector("u_real", "input")}{connector("y_real", "output")}</ssd:Connectors>
</ssd:Component>
</ssd:Elements>
<ssd:Connections>
{conn("flex.x", "busIn.angle")}{conn("busOut.angle", "sensor.u")}
{conn("decay.x", "plantIn.decay", inner=linear(10.0))}
{conn("plantOut.decay", "echo.u_real", inner=linear(1.0, -5.0))}
</ssd:Connections>
<ssd:SignalDictionaries>
<ssd:SignalDictionary name="nav"><ssb:SignalDictionary version="1.0">
<ssb:DictionaryEntry name="angle"><ssc:Real unit="rad"/></ssb:DictionaryEntry>
</ssb:SignalDictionary></ssd:SignalDictionary>
<ssd:SignalDictionary name="plant" source="resources/plant.ssb"/>
</ssd:SignalDictionaries>
</ssd:System>
<ssd:Units><ssc:Unit name="rad"><ssc:BaseUnit rad="1"/></ssc:Unit></ssd:Units>
"""
    + TAIL
)

# 5. linear transformations with offsets, with and without unit conversion
OFFSETS = (
    HEAD.format(version="1.0", name="Offsets")
    + f"""<ssd:System name="Shifted"><ssd:Elements>
<ssd:Component name="flex" source="resources/GaussMarkov2.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output")}</ssd:Connectors>{GAUSS_MARKOV_SET}
</ssd:Component>
<ssd:Component name="decay" source="resources/Decay.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output")}</ssd:Connectors>
</ssd:Component>
<ssd:Component name="sensor" source="resources/FirstOrderSensor.fmu" {FMU}>
<ssd:Connectors>{connector("u", "input")}{connector("y", "output")}</ssd:Connectors>
</ssd:Component>
<ssd:Component name="echo" source="resources/Echo.fmu" {FMU}>
<ssd:Connectors>{connector("u_real", "input")}{connector("y_real", "output")}</ssd:Connectors>
</ssd:Component>
</ssd:Elements>
<ssd:Connections>
{conn("flex.x", "sensor.u", ' suppressUnitConversion="true"', linear(1.0, 0.01))}
{conn("decay.x", "echo.u_real", inner=linear(3.0, -0.5))}
</ssd:Connections>
</ssd:System>
"""
    + TAIL
)

# 6. SSP 2.0 that keeps the SSP 1 namespaces: Float64 / Int32 connectors and values
SSP2 = (
    HEAD.format(version="2.0", name="Ssp2")
    + f"""<ssd:System name="Two"><ssd:Elements>
<ssd:Component name="decay" source="resources/Decay.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output", "Float64")}{connector("n_int", "output", "Int32")}
</ssd:Connectors>
{pset("decay", real("k", 1.5, kind="Float64") + real("x0", 3.0, kind="Float64"))}
</ssd:Component>
<ssd:Component name="echo" source="resources/Echo.fmu" {FMU}>
<ssd:Connectors>{connector("u_real", "input", "Float64")}
{connector("y_real", "output", "Float64")}</ssd:Connectors>
{pset("echo", real("p_real", 0.5, kind="Float64") + integer("p_int", 4, "Int32"))}
</ssd:Component>
<ssd:Component name="sensor" source="resources/FirstOrderSensor.fmu" {FMU}>
<ssd:Connectors>{connector("u", "input", "Float64")}{connector("y", "output", "Float64")}
</ssd:Connectors>
</ssd:Component>
</ssd:Elements>
<ssd:Connections>
{conn("decay.x", "echo.u_real", inner=linear(2.0, 0.25))}
{conn("echo.y_real", "sensor.u", ' suppressUnitConversion="true"')}
</ssd:Connections>
</ssd:System>
"""
    + TAIL
).replace('version="1.0" name="decay"', 'version="2.0" name="decay"')

ENUM_MID = '<ssv:Parameter name="u_enum"><ssv:Enumeration value="mid"/></ssv:Parameter>'
# 7. typed connectors: every FMI 2 type declared (links between non-Real variables are
# run by the master from the "typed" branch on; here they are imported and checked)
TYPED = (
    HEAD.format(version="1.0", name="Typed")
    + f"""<ssd:System name="Types"><ssd:Elements>
<ssd:Component name="decay" source="resources/Decay.fmu" {FMU}>
<ssd:Connectors>{connector("x", "output")}{connector("n_int", "output", "Integer")}
</ssd:Connectors>
</ssd:Component>
<ssd:Component name="echo" source="resources/Echo.fmu" {FMU}>
<ssd:Connectors>{connector("u_real", "input")}{connector("u_int", "input", "Integer")}
{connector("u_bool", "input", "Boolean")}{connector("u_str", "input", "String")}
{connector("u_enum", "input", "Enumeration", ' name="Level"')}
{connector("y_int", "output", "Integer")}{connector("y_bool", "output", "Boolean")}
{connector("y_str", "output", "String")}
{connector("y_enum", "output", "Enumeration", ' name="Level"')}</ssd:Connectors>
{pset("echo", integer("p_int", 2) + ENUM_MID)}
</ssd:Component>
</ssd:Elements>
<ssd:Connections>{conn("decay.x", "echo.u_real")}</ssd:Connections>
</ssd:System>
<ssd:Enumerations><ssc:Enumeration name="Level"><ssc:Item name="low" value="1"/>
<ssc:Item name="mid" value="2"/><ssc:Item name="high" value="3"/></ssc:Enumeration>
</ssd:Enumerations>
"""
    + TAIL
)

ARCHIVES: dict[str, tuple[str, dict[str, str]]] = {
    "hierarchy": (HIERARCHY, {}),
    "mapping": (MAPPING, {"resources/echo.ssm": SSM, "resources/echo.ssv": ECHO_SET}),
    "units": (UNITS, {"resources/sensor.ssv": SENSOR_SET}),
    "dictionary": (DICTIONARY, {"resources/plant.ssb": SSB}),
    "offsets": (OFFSETS, {}),
    "ssp2": (SSP2, {}),
    "typed": (TYPED, {}),
}


def write(path: Path, fmus: dict[str, Path], ssd: str, files: dict[str, str]) -> Path:
    """Zip ``ssd``, ``files`` and the FMUs (as ``resources/<name>``) into ``path``."""
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        for member, text in files.items():
            zf.writestr(member, text)
        for name, fmu in fmus.items():
            zf.write(fmu, f"resources/{name}")
    return path
