"""Modules held off a build (``roadtwin._lazy``) are still there for whoever uses them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

DATA = Path(__file__).parent / "data" / "xodr"


def _run(code: str) -> list[str]:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return out.stdout.split("\n")


def test_writing_a_map_does_not_import_xmlschema_yet_schema_checks_and_xosc_still_work(
    tmp_path,
):
    """scenariogeneration imports xmlschema (0.16 s) for reading OpenSCENARIO files, which
    writing a map never does: after a write it is a stand-in, not imported. The schema
    check and scenariogeneration's own reader use it afterwards as usual."""
    code = f"""
import sys
from roadtwin.xodr import read_xodr, schema_errors, write_xodr
net = read_xodr({str(DATA / "e6mini.xodr")!r})
write_xodr(net, {str(tmp_path / "map.xodr")!r})
print("xmlschema.validators" in sys.modules, type(sys.modules["xmlschema"]).__name__)
print(len(schema_errors({str(tmp_path / "map.xodr")!r})), "xmlschema.validators" in sys.modules)
import scenariogeneration.xosc.xosc_reader as reader
print(reader.xmlschema.XMLSchema.__name__)
"""
    assert _run(code)[:3] == ["False _StandIn", "0 True", "XMLSchema10"]


def test_a_stand_in_for_a_module_already_imported_or_missing_is_not_bound():
    code = """
import sys
import json
from roadtwin._lazy import bind_lazily
bind_lazily("json")
bind_lazily("no_such_module_here")
print(sys.modules["json"] is json, "no_such_module_here" in sys.modules)
"""
    assert _run(code)[0] == "True False"
