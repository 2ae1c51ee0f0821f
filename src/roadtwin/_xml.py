"""Safe XML parsing for every XML file roadtwin reads (OpenDRIVE maps and truths, OSM XML).

Input XML is parsed with DTD loading, entity expansion and network access switched off
(lxml ``load_dtd=False, resolve_entities=False, no_network=True``), XInclude is never
processed, and libxml2's size and depth limits stay on (no ``huge_tree``). A document
whose DTD declares entities is refused: no roadtwin input needs them, and they are how
"billion laughs" and external-entity attacks (a map that pulls ``/etc/passwd`` into a link
target) work. OSM extracts are read by libosmium (pyosmium), which refuses entity
declarations itself ("XML entities are not supported"); OSMnx only ever reads the cropped
XML that roadtwin writes.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import IO

from lxml import etree

from ._errors import InputError

__all__ = ["parse_xml", "safe_parser"]


def safe_parser(**options) -> etree.XMLParser:
    """An lxml parser with DTDs, entities and network access off.

    ``options`` are further :class:`lxml.etree.XMLParser` keywords (``remove_comments``).
    """
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        **options,
    )


def parse_xml(
    source: str | os.PathLike | bytes | IO[bytes], *, name: str | os.PathLike | None = None
) -> etree._ElementTree:
    """Parse untrusted XML safely (see the module docstring).

    Parameters
    ----------
    source
        File path, bytes, or a binary file object (e.g. from ``gzip.open``).
    name
        How to name the document in error messages (default: the path).

    Raises
    ------
    InputError
        Not well-formed XML, over libxml2's limits, or a DTD that declares entities.
    """
    label = str(name if name is not None else source if isinstance(source, (str, Path)) else "XML")
    parser = safe_parser(remove_comments=True)
    try:
        if isinstance(source, bytes):
            tree = etree.ElementTree(etree.fromstring(source, parser))
        elif isinstance(source, (str, os.PathLike)):
            tree = etree.parse(os.fspath(source), parser)
        else:
            tree = etree.parse(source, parser)
    except etree.XMLSyntaxError as exc:
        reason = " ".join(str(exc).split())
        msg = f"{label}: not well-formed XML ({reason})"
        raise InputError(msg) from None
    dtd = tree.docinfo.internalDTD
    if dtd is not None and any(True for _ in dtd.iterentities()):
        msg = (
            f"{label}: the XML declares entities in a DTD (<!ENTITY ...>); roadtwin does not "
            "expand entities (they can read local files or explode in size): remove the DTD"
        )
        raise InputError(msg)
    return tree
