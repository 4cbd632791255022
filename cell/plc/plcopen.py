"""One PLCopen TC6 XML file (v2.01) holding the whole library, for CODESYS and the environments built on it.

Types go to ``types/dataTypes``, the blocks and MAIN to ``types/pous`` (interfaces as variable lists,
bodies as structured text), the global lists to ``instances/configurations`` as a configuration's
``globalVars``; the configuration's resource holds the task that runs MAIN (a ``pouInstance``), as an
IEC 61131-3 configuration declares its resources and tasks (PLCopen TC6 v2.01, ``instances``). A struct
that must be packed carries ``pack_mode`` as CODESYS writes an attribute (in ``addData``), since the
schema has no place for pragmas. The file carries no time of its own: ``creationDateTime`` is fixed, so
the same contract and map give the same bytes.
"""

from __future__ import annotations

from xml.sax.saxutils import escape, quoteattr

from .model import (
    ArrayType,
    Elementary,
    Enum,
    Gvl,
    Library,
    Pou,
    StringType,
    Struct,
    Task,
    Type,
    Var,
    VarList,
)
from .twincat import cdata

NS = "http://www.plcopen.org/xml/tc6_0201"
XHTML = "http://www.w3.org/1999/xhtml"
CREATED = "2000-01-01T00:00:00"
_POU_TYPES = {"FUNCTION_BLOCK": "functionBlock", "PROGRAM": "program"}
# a struct packed without gaps, as CODESYS writes a pragma attribute in its PLCopen XML
PACKED = ('<addData><data name="http://www.3s-software.com/plcopenxml/attributes" handleUnknown="implementation">'
          '<Attributes><Attribute Name="pack_mode" Value="1"/></Attributes></data></addData>')
_LISTS = {"VAR_INPUT": "inputVars", "VAR_OUTPUT": "outputVars", "VAR": "localVars", "VAR_GLOBAL": "globalVars"}


def _text(text: str, tag: str = "documentation") -> str:
    return f'<{tag}><xhtml:p xmlns:xhtml="{XHTML}">{cdata(text)}</xhtml:p></{tag}>'


def type_xml(t: Type) -> str:
    if isinstance(t, Elementary):
        return f"<{t.name}/>"
    if isinstance(t, StringType):
        return f'<string length="{t.length}"/>'
    if isinstance(t, ArrayType):
        return (f'<array><dimension lower="{t.lower}" upper="{t.upper}"/><baseType>{type_xml(t.base)}</baseType>'
                "</array>")
    return f"<derived name={quoteattr(t.name)}/>"


def variable(v: Var) -> str:
    init = f"<initialValue><simpleValue value={quoteattr(v.init)}/></initialValue>" if v.init else ""
    doc = _text(v.comment) if v.comment else ""
    at = f" address={quoteattr(v.at)}" if v.at else ""         # TC6 XML's located variable
    return f"<variable name={quoteattr(v.name)}{at}><type>{type_xml(v.type)}</type>{init}{doc}</variable>"


def _var_list(vl: VarList, tag: str) -> str:
    constant = ' constant="true"' if vl.constant else ""
    return f"<{tag}{constant}>" + "".join(variable(v) for v in vl.vars) + f"</{tag}>"


def data_type(obj: Struct | Enum) -> str:
    if isinstance(obj, Struct):
        base = "<struct>" + "".join(variable(v) for v in obj.fields) + "</struct>"
    else:
        values = "".join(f"<value name={quoteattr(n)} value={quoteattr(str(x))}/>" for n, x, _ in obj.values)
        base = f"<enum><values>{values}</values><baseType>{type_xml(obj.base)}</baseType></enum>"
    doc = _text(obj.comment) if obj.comment else ""
    pack = PACKED if isinstance(obj, Struct) and obj.pack else ""
    return f"<dataType name={quoteattr(obj.name)}><baseType>{base}</baseType>{pack}{doc}</dataType>"


def pou(obj: Pou) -> str:
    lists = "".join(_var_list(vl, _LISTS[vl.kind]) for vl in obj.lists)
    doc = _text(obj.comment) if obj.comment else ""
    return (f"<pou name={quoteattr(obj.name)} pouType=\"{_POU_TYPES[obj.kind]}\"><interface>{lists}</interface>"
            f"<body>{_text(obj.body, 'ST')}</body>{doc}</pou>")


def global_lists(gvls: list[Gvl]) -> str:
    out = []
    for g in gvls:
        for vl in g.lists:
            constant = ' constant="true"' if vl.constant else ""
            body = "".join(variable(v) for v in vl.vars)
            out.append(f"<globalVars name={quoteattr(g.name)}{constant}>{body}{_text(g.comment)}</globalVars>")
    return "".join(out)


def resource(task: Task | None) -> str:
    """The configuration's one resource, with the task that runs the example program (IEC duration ``T#1MS``)."""
    if task is None:
        return '<resource name="PLC"/>'
    return (f'<resource name="PLC"><task name={quoteattr(task.name)} interval="T#{task.interval_ms:g}MS" '
            f'priority="{task.priority}"><pouInstance name={quoteattr(task.program)} '
            f'typeName={quoteattr(task.program)}/></task></resource>')


def project(lib: Library, name: str = "StiffComp") -> bytes:
    """The PLCopen XML file of ``lib``."""
    parts = [
        '<?xml version="1.0" encoding="utf-8"?>\n',
        f'<project xmlns="{NS}">\n',
        (f'<fileHeader companyName="stiffcomp" productName="stiffcomp plc-library" productVersion="1" '
         f'creationDateTime="{CREATED}"/>\n'),
        (f'<contentHeader name={quoteattr(name)}><coordinateInfo><fbd><scaling x="1" y="1"/></fbd>'
         '<ld><scaling x="1" y="1"/></ld><sfc><scaling x="1" y="1"/></sfc></coordinateInfo></contentHeader>\n'),
        "<types>\n<dataTypes>\n", *(data_type(t) + "\n" for t in lib.types), "</dataTypes>\n<pous>\n",
        *(pou(p) + "\n" for p in lib.pous), "</pous>\n</types>\n",
        (f'<instances><configurations><configuration name="{escape(name)}">\n{resource(lib.task)}\n'
         f"{global_lists(lib.gvls)}\n</configuration></configurations></instances>\n</project>\n")]
    return "".join(parts).encode("utf-8")
