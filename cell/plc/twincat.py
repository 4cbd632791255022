"""TwinCAT 3's source files: one XML file per object (``.TcDUT``, ``.TcGVL``, ``.TcPOU``).

Each holds the object's structured text in CDATA, as TwinCAT writes it; the object's GUID is derived
from its name (uuid5), so the files are the same bytes each time they are generated.
"""

from __future__ import annotations

import uuid

from .model import Enum, Gvl, Library, Pou, Struct, declaration

HEAD = '<?xml version="1.0" encoding="utf-8"?>\n<TcPlcObject Version="1.1.0.1" ProductVersion="3.1.4024.12">\n'
NAMESPACE = uuid.UUID("6f1c3a52-7d0e-5b8e-9a43-5c7e2f0d1b64")      # this library's names


def guid(name: str) -> str:
    return "{" + str(uuid.uuid5(NAMESPACE, name)) + "}"


def cdata(text: str) -> str:
    return "<![CDATA[" + text.replace("]]>", "]]]]><![CDATA[>") + "]]>"


def object_file(obj: Struct | Enum | Gvl | Pou) -> tuple[str, bytes]:
    """(file name, contents) of one object."""
    decl = f"    <Declaration>{cdata(declaration(obj))}</Declaration>\n"
    if isinstance(obj, Pou):
        tag, ext = "POU", "TcPOU"
        inner = (decl + f"    <Implementation>\n      <ST>{cdata(obj.body)}</ST>\n    </Implementation>\n")
        attrs = ' SpecialFunc="None"'
    else:
        tag, ext = ("GVL", "TcGVL") if isinstance(obj, Gvl) else ("DUT", "TcDUT")
        inner, attrs = decl, ""
    text = (HEAD + f'  <{tag} Name="{obj.name}" Id="{guid(obj.name)}"{attrs}>\n' + inner + f"  </{tag}>\n"
            "</TcPlcObject>\n")
    return f"{obj.name}.{ext}", text.encode("utf-8")


def files(lib: Library) -> dict[str, bytes]:
    """File name -> contents, for every object of ``lib``."""
    return dict(object_file(o) for o in (*lib.types, *lib.gvls, *lib.pous))
