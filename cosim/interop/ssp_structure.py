"""The structure of an SSP system flattened into FMU components and component-to-component links.

:func:`flatten` walks ``ssd:System`` and its sub-systems:

- a component of sub-system ``deck`` named ``imu`` becomes the block ``deck_imu`` (the
  path joined by ``_``; a name that is taken or not an identifier is refused);
- a connection through a sub-system's connector (``startElement="deck"`` outside,
  no ``startElement`` inside ``deck``) and through a signal dictionary (a component
  writes ``ref.entry`` of an ``ssd:SignalDictionaryReference``; every reference to the
  same dictionary reads it) is followed to the component inputs at its ends; each hop's
  ``ssc:LinearTransformation`` composes (``y = factor * x + offset``, applied after the
  unit conversion); units convert between the two FMUs' own units at the ends (not
  when a hop says ``suppressUnitConversion="true"``);
- connector types (``ssc:Real`` .. ``ssc:Enumeration``, SSP 2.0's ``ssc:Float64``,
  ``ssc:Int32`` ..) are checked: a component's connector must declare the type of its
  FMU variable, a sub-system connector or dictionary entry on the way must declare the
  source's type, and the two ends must have the same type (FMI's rule); a linear
  transformation on a link that is not Real is refused.

What cannot be flattened is refused in one line naming the element: connections into
the top-level system's own connectors from outside (nothing outside the archive feeds
them), a dictionary entry written twice, ``Boolean`` / ``Integer`` /
``EnumerationMappingTransformation`` on connections, a loop of system connectors.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from xml.etree import ElementTree as ET

from cosim.interop.ssp_xml import NS, SSD_FILE, Archive, connector_type, local

#: A node of the connection graph: ("comp", block, connector), ("sys", path, connector)
#: or ("dict", dictionary key, entry).
Node = tuple[str, str, str]


@dataclass
class Hop:
    """One ``ssd:Connection`` between two nodes.

    Attributes
    ----------
    start, end : Node
        The nodes it joins.
    factor, offset : float
        Its ``ssc:LinearTransformation`` (1 and 0 without one).
    suppress : bool
        ``suppressUnitConversion``.
    where : str
        How errors name it.
    """

    start: Node
    end: Node
    factor: float
    offset: float
    suppress: bool
    where: str


@dataclass
class Link:
    """One resolved link from a component output to a component input.

    Attributes
    ----------
    start, end : (str, str)
        (block, FMU variable name).
    factor, offset : float
        The composed linear transformation ``y = factor * x + offset`` [end unit].
    suppress : bool
        Whether a hop suppresses the unit conversion (then only ``factor`` scales).
    where : str
        The first connection of the path, as errors name it.
    via : tuple
        The system connectors and dictionary entries on the way (nodes).
    """

    start: tuple[str, str]
    end: tuple[str, str]
    factor: float
    offset: float
    suppress: bool
    where: str
    via: tuple[Node, ...] = ()


@dataclass
class Flat:
    """A system flattened: its components by block name and the hops between nodes.

    Attributes
    ----------
    components : dict
        Block name -> (component element, how errors name it).
    paths : dict
        Element path (sub-systems and components) -> block name, or "" for a sub-system.
    systems : dict
        System path (``()`` for the top) -> its ``ssd:System`` element.
    hops : list of Hop
        Every connection of every system.
    types : dict
        Declared type of each system connector / dictionary entry node that declares one.
    """

    components: dict[str, tuple[ET.Element, str]] = field(default_factory=dict)
    paths: dict[tuple[str, ...], str] = field(default_factory=dict)
    systems: dict[tuple[str, ...], ET.Element] = field(default_factory=dict)
    hops: list[Hop] = field(default_factory=list)
    types: dict[Node, str] = field(default_factory=dict)


def block_name(path: tuple[str, ...]) -> str:
    """The block name of a component at ``path`` (``("deck", "imu")`` -> ``deck_imu``).

    Parameters
    ----------
    path : tuple of str
        Sub-system names, then the component's name.

    Returns
    -------
    str
    """
    return "_".join(path)


def flatten(archive: Archive, top: ET.Element) -> Flat:
    """Collect the components, sub-systems and connections of ``top`` and below.

    Parameters
    ----------
    archive : Archive
        For errors and signal dictionary files.
    top : Element
        The SSD's ``ssd:System``.

    Returns
    -------
    Flat
    """
    flat = Flat()
    flat.systems[()] = top
    _walk(archive, flat, top, (), {})
    return flat


def _walk(
    archive: Archive,
    flat: Flat,
    system: ET.Element,
    path: tuple[str, ...],
    dictionaries: dict[str, str],
) -> None:
    sys_label = f"System '{'/'.join(path) if path else system.get('name', '')}'"
    dictionaries = dict(dictionaries)
    for d in system.findall("ssd:SignalDictionaries/ssd:SignalDictionary", NS):
        key = "/".join((*path, d.get("name", "")))
        dictionaries[d.get("name", "")] = key
        _dictionary(archive, flat, d, key, sys_label)
    for sub in system.findall("ssd:Connectors/ssd:Connector", NS):
        declared = connector_type(sub)
        if declared and path:
            flat.types[("sys", "/".join(path), sub.get("name", ""))] = declared[0]
    kinds: dict[str, str] = {}
    for el in system.findall("ssd:Elements/*", NS):
        name = el.get("name", "")
        kind = local(el.tag)
        where = f"{sys_label}/{kind} '{name}'"
        if name in kinds:
            raise archive.error(SSD_FILE, where, "two elements of one system share this name")
        kinds[name] = kind
        if kind == "Component":
            block = block_name((*path, name))
            if not re.match(r"^[A-Za-z_]\w*$", block):
                raise archive.error(
                    SSD_FILE, where, "component names must be Python-style identifiers here"
                )
            if block in flat.components:
                raise archive.error(
                    SSD_FILE,
                    where,
                    f"its flattened name '{block}' (sub-system path joined by '_') is taken "
                    f"by {flat.components[block][1]}; rename one",
                )
            flat.components[block] = (el, where)
            flat.paths[(*path, name)] = block
        elif kind == "System":
            flat.paths[(*path, name)] = ""
            flat.systems[(*path, name)] = el
            _walk(archive, flat, el, (*path, name), dictionaries)
        elif kind == "SignalDictionaryReference":
            dictionary = el.get("dictionary", "")
            if dictionary not in dictionaries:
                raise archive.error(
                    SSD_FILE,
                    where,
                    f"no ssd:SignalDictionary '{dictionary}' in this system or above it "
                    f"(defined: {', '.join(dictionaries) or 'none'})",
                )
            kinds[name] = f"dict:{dictionaries[dictionary]}"
    for c in system.findall("ssd:Connections/ssd:Connection", NS):
        flat.hops.append(_hop(archive, c, path, kinds, sys_label))


def _dictionary(archive: Archive, flat: Flat, d: ET.Element, key: str, owner: str) -> None:
    """Record the declared entry types of one signal dictionary (inline or ``.ssb``)."""
    where = f"{owner}/SignalDictionary '{d.get('name', '')}'"
    if d.get("source") is not None:
        inner = archive.member(d.get("source", ""), (SSD_FILE, f"{where} source"), "an .ssb file")
        root = archive.xml(inner, "SystemStructureSignalDictionary.xsd", (SSD_FILE, where))
    else:
        found = d.find("ssb:SignalDictionary", NS)
        if found is None:
            raise archive.error(SSD_FILE, where, "no ssb:SignalDictionary inside and no source")
        root = found
    for entry in root.findall("ssb:DictionaryEntry", NS):
        declared = connector_type(entry)
        if declared:
            flat.types[("dict", key, entry.get("name", ""))] = declared[0]


def _hop(
    archive: Archive, c: ET.Element, path: tuple[str, ...], kinds: dict[str, str], label: str
) -> Hop:
    se, sc = c.get("startElement"), c.get("startConnector", "")
    ee, ec = c.get("endElement"), c.get("endConnector", "")
    where = f"Connection {se or '(system)'}.{sc} -> {ee or '(system)'}.{ec}"
    if path:
        where = f"{label}/{where}"
    if not path and not se:
        raise archive.error(
            SSD_FILE,
            where,
            "the top-level system's connector has no source outside the archive; "
            "connect a component's output instead",
        )

    def node(element: str | None, connector: str) -> Node:
        if not element:
            return ("sys", "/".join(path), connector)
        kind = kinds.get(element)
        if kind is None:
            raise archive.error(SSD_FILE, where, f"no element '{element}' in the system")
        if kind == "Component":
            return ("comp", block_name((*path, element)), connector)
        if kind == "System":
            return ("sys", "/".join((*path, element)), connector)
        return ("dict", kind.removeprefix("dict:"), connector)

    factor, offset = 1.0, 0.0
    for t in c:
        tag = local(t.tag)
        if tag == "LinearTransformation":
            factor, offset = float(t.get("factor", 1.0)), float(t.get("offset", 0.0))
        elif tag.endswith("MappingTransformation"):
            raise archive.error(
                SSD_FILE,
                f"{where}/{tag}",
                f"{tag} on a connection is not supported; map the values inside the FMU "
                f"or connect equal values (an ssc:LinearTransformation is supported)",
            )
    return Hop(
        start=node(se, sc),
        end=node(ee, ec),
        factor=factor,
        offset=offset,
        suppress=c.get("suppressUnitConversion", "false") in ("true", "1"),
        where=where,
    )


def resolve_links(archive: Archive, flat: Flat) -> tuple[list[Link], list[str]]:
    """Follow every hop from a component output to the component inputs it reaches.

    Parameters
    ----------
    archive : Archive
        For errors.
    flat : Flat
        From :func:`flatten`.

    Returns
    -------
    links : list of Link
        One per (output, input) pair, with the composed transformation.
    dead_ends : list of str
        Paths that end at the top-level system's connectors (exposed outputs, unused).
    """
    out: dict[Node, list[Hop]] = {}
    writers: dict[Node, Hop] = {}
    for hop in flat.hops:
        out.setdefault(hop.start, []).append(hop)
        if hop.end[0] == "dict":
            if hop.end in writers:
                raise archive.error(
                    SSD_FILE,
                    hop.where,
                    f"the signal dictionary entry '{hop.end[2]}' is already written by "
                    f"{writers[hop.end].where}; an entry has one writer",
                )
            writers[hop.end] = hop
    links: list[Link] = []
    dead: list[str] = []
    for hop in flat.hops:
        if hop.start[0] != "comp":
            continue
        seen0: tuple[tuple[str, str, str], ...] = (hop.start,)
        stack = [(hop, hop.factor, hop.offset, hop.suppress, seen0)]
        while stack:
            h, f, o, s, seen = stack.pop()
            end = h.end
            if end[0] == "comp":
                start = (hop.start[1], hop.start[2])
                links.append(Link(start, (end[1], end[2]), f, o, s, hop.where, seen[1:]))
                continue
            if end in seen:
                raise archive.error(SSD_FILE, h.where, "the connection closes a loop")
            following = out.get(end, [])
            if not following and end[0] == "sys" and end[1] == "":
                dead.append(f"{hop.start[1]}.{hop.start[2]} -> (system).{end[2]}")
            for nxt in following:
                # y = f2 (f1 x + o1) + o2
                f2, o2 = nxt.factor * f, nxt.factor * o + nxt.offset
                stack.append((nxt, f2, o2, s or nxt.suppress, (*seen, end)))
    return links, dead
