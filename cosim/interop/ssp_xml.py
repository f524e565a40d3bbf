"""Reading the XML files of an SSP archive: the zip, schema validation, versions, units.

Used by :mod:`cosim.interop.ssp_import` (and the modules it splits into). Every file of
the archive that is read (``SystemStructure.ssd``, ``.ssv``, ``.ssm``, ``.ssb``) is
validated against the SSP 1.0 schemas that fmpy ships before it is used.

SSP versions: ``version="1.0"`` (and ``1.x``) as they are. SSP 2.0 keeps the SSP 1
namespace URIs (``http://ssp-standard.org/SSP1/...``) and marks its files
``version="2.0"``; its connector and parameter types add FMI 3's ``Float64``,
``Float32``, ``Int8`` .. ``UInt64`` (and ``Binary``, ``Clock``). A 2.0 file is
validated as the 1.0 file it would be with these types written as ``Real`` /
``Integer`` (:data:`SSP2_TYPES`); what still fails the 1.0 schemas (an element SSP 2.0
added) is refused in one line naming it. The types themselves are kept: a connector
``ssc:Float64`` is a Real connector, ``ssc:Int32`` an Integer one.
"""

from __future__ import annotations

import zipfile
from pathlib import Path, PurePosixPath
from xml.etree import ElementTree as ET

from cosim.archives import check_archive
from cosim.errors import ScenarioError, UnitError
from cosim.units import Unit, unit_from_fmi

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
SSM = "http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
SSB = "http://ssp-standard.org/SSP1/SystemStructureSignalDictionary"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
INS = "urn:ins-cosim:ssp"
NS = {"ssd": SSD, "ssc": SSC, "ssv": SSV, "ssm": SSM, "ssb": SSB, "osp": OSP, "ic": INS}
SSD_FILE = "SystemStructure.ssd"
#: SSP 2.0 value types -> the SSP 1.0 type that validates in their place.
SSP2_TYPES = {
    "Float64": "Real",
    "Float32": "Real",
    "Int8": "Integer",
    "UInt8": "Integer",
    "Int16": "Integer",
    "UInt16": "Integer",
    "Int32": "Integer",
    "UInt32": "Integer",
    "Int64": "Integer",
    "UInt64": "Integer",
}
#: Connector / entry type element -> the ins-cosim variable type it stands for.
CONNECTOR_TYPES = {
    "Real": "Real",
    "Float64": "Real",
    "Integer": "Integer",
    "Int32": "Integer",
    "Boolean": "Boolean",
    "String": "String",
    "Enumeration": "Enumeration",
    "Binary": "Binary",
    "Float32": "Float32",
    "Int8": "Int8",
    "UInt8": "UInt8",
    "Int16": "Int16",
    "UInt16": "UInt16",
    "UInt32": "UInt32",
    "Int64": "Int64",
    "UInt64": "UInt64",
}
_BASE_ATTRS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


class SspImportError(ScenarioError):
    """An SSP archive cannot be imported; the message names the archive, file and element."""


def local(tag: str) -> str:
    """The local name of an ElementTree tag.

    Parameters
    ----------
    tag : str
        ``{namespace}Real``.

    Returns
    -------
    str
        ``Real``.
    """
    return tag.rsplit("}", 1)[-1]


class Archive:
    """The zip file, its parsed XML files and the place errors point to.

    Parameters
    ----------
    path : Path
        The ``.ssp`` file (checked against the unpack limits before anything is read).
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.version = "1.0"
        if path.is_file() and zipfile.is_zipfile(path):
            check_archive(path, "SSP archive")  # the unpack limits, before any member is read
        try:
            self.zip = zipfile.ZipFile(path)
        except (OSError, zipfile.BadZipFile) as exc:
            raise SspImportError(
                f"not an SSP archive ({exc}); expected a zip file with SystemStructure.ssd",
                file=str(path),
            ) from None
        self.names = set(self.zip.namelist())

    def error(self, inner: str, element: str, message: str) -> SspImportError:
        """A one-line error naming ``archive!inner`` and the element.

        Parameters
        ----------
        inner : str
            The file inside the archive.
        element : str
            The element (as the message's key).
        message : str
            What is wrong and how to fix it.

        Returns
        -------
        SspImportError
        """
        return SspImportError(message, file=f"{self.path}!{inner}", key=element)

    def member(self, source: str, referrer: tuple[str, str], expect: str) -> str:
        """The archive member a ``source`` attribute names (relative, inside the archive).

        Parameters
        ----------
        source : str
            The attribute's value.
        referrer : (str, str)
            The file and element that name it.
        expect : str
            What it should be (for the error).

        Returns
        -------
        str
            The member's name.
        """
        inner = str(PurePosixPath(source.removeprefix("./")))
        if ":" in source or inner.startswith("..") or inner not in self.names:
            raise self.error(
                referrer[0],
                referrer[1],
                f"{source!r} is not a file inside the archive; expected {expect}",
            )
        return inner

    def xml(self, inner: str, schema: str, referrer: tuple[str, str]) -> ET.Element:
        """Parse and validate one XML file of the archive.

        Parameters
        ----------
        inner : str
            The member's path inside the archive.
        schema : str
            The SSP 1.0 schema file it must validate against.
        referrer : (str, str)
            The file and element that name it (for the error when it is missing).

        Returns
        -------
        xml.etree.ElementTree.Element
            Its root.
        """
        if inner not in self.names:
            raise self.error(
                referrer[0],
                referrer[1],
                f"'{inner}' is not in the archive (it holds: {', '.join(sorted(self.names))})",
            )
        data = self.zip.read(inner)
        self.validate(data, schema, inner)
        return ET.fromstring(data)

    def validate(self, data: bytes, schema: str, inner: str) -> None:
        """Validate against the SSP 1.0 schema fmpy ships (lxml); first error in one line.

        Parameters
        ----------
        data : bytes
            The file's content.
        schema : str
            The schema file name.
        inner : str
            The file's name inside the archive.
        """
        from fmpy.ssp import ssd as fmpy_ssd
        from lxml import etree

        folder = Path(fmpy_ssd.__file__).parent / "schema"
        try:
            doc = etree.fromstring(data)
        except etree.XMLSyntaxError as exc:
            raise self.error(inner, "XML", f"not well-formed XML: {exc}") from None
        version = doc.get("version") or "1.0"
        name = etree.QName(doc).localname
        if version.startswith("2."):
            if inner == SSD_FILE:
                self.version = version
            for el in doc.iter():
                if not isinstance(el.tag, str):
                    continue
                if el.get("version", "").startswith("2."):
                    el.set("version", "1.0")
                q = etree.QName(el)
                if q.namespace == SSC and q.localname in SSP2_TYPES:
                    el.tag = f"{{{SSC}}}{SSP2_TYPES[q.localname]}"
                elif q.namespace == SSV and q.localname in SSP2_TYPES:
                    el.tag = f"{{{SSV}}}{SSP2_TYPES[q.localname]}"
        elif not version.startswith("1."):
            raise self.error(
                inner,
                f"{name} version",
                f"SSP version {version!r}; ins-cosim imports SSP 1.0 and 2.0 "
                f'(version="1.0" or "2.0")',
            )
        validator = etree.XMLSchema(file=str(folder / schema))
        if not validator.validate(doc):
            first = validator.error_log[0]
            also = (
                " (an SSP 2.0 element that ins-cosim does not import; leave it out)"
                if version.startswith("2.")
                else ""
            )
            raise self.error(
                inner,
                f"line {first.line}",
                f"does not validate against the SSP 1.0 schema {schema}{also}: {first.message}",
            )


def read_units(parent: ET.Element | None, path: str) -> dict[str, Unit]:
    """``ssc:Unit`` definitions under ``parent`` (``ssd:Units``, ``ssv:Units``, ...).

    Parameters
    ----------
    parent : Element or None
        The ``Units`` element.
    path : str
        ``archive!file`` for errors.

    Returns
    -------
    dict
        Unit name -> :class:`~cosim.units.Unit`.
    """
    out: dict[str, Unit] = {}
    if parent is None:
        return out
    for u in parent.findall("ssc:Unit", NS):
        base = u.find("ssc:BaseUnit", NS)
        attrs = base.attrib if base is not None else {}
        exponents = {k: float(attrs.get(k, 0)) for k in _BASE_ATTRS}
        name = u.get("name", "")
        try:
            out[name] = unit_from_fmi(
                name, exponents, float(attrs.get("factor", 1.0)), float(attrs.get("offset", 0.0))
            )
        except UnitError as exc:
            raise SspImportError(exc.message, file=path, key=f"Unit '{name}'") from None
    return out


def connector_type(element: ET.Element) -> tuple[str, ET.Element] | None:
    """The declared type of a connector or dictionary entry and its type element.

    Parameters
    ----------
    element : Element
        The ``ssd:Connector`` or ``ssb:DictionaryEntry``.

    Returns
    -------
    (str, Element) or None
        The ins-cosim variable type (``ssc:Float64`` -> ``"Real"``) and the element, or
        None when the connector declares no type.
    """
    for child in element:
        if child.tag.startswith(f"{{{SSC}}}") and local(child.tag) in CONNECTOR_TYPES:
            return CONNECTOR_TYPES[local(child.tag)], child
    return None
