"""Every XML reader refuses every XML attack and never reads the secret file (issue 13).

Readers: the OpenDRIVE reader (``read_xodr``, used by ``check`` and ``evaluate``), the
truth loader, ``check_file``, the OSM loader (libosmium through pyosmium, for ``.osm``,
``.osm.gz`` and ``.osm.bz2``), the simulator's OSM cropper, and ``parse_xml`` on bytes.
Attacks: billion laughs, an external entity, a parameter entity that defines an entity
holding a local file, and XInclude.
"""

from __future__ import annotations

import bz2
import gzip
import shutil
from pathlib import Path

import pytest

import corpus
from roadtwin._errors import InputError
from roadtwin._xml import parse_xml
from roadtwin.check import check_file
from roadtwin.evaluation import load_truth
from roadtwin.frames import MappingFrame, Origin
from roadtwin.osm import load_osm
from roadtwin.simulate.from_osm import crop_osm
from roadtwin.xodr import read_xodr

DATA = Path(__file__).parent / "data"
XODR = DATA / "xodr" / "e6mini.xodr"
ATTACKS = list(corpus.XML_ATTACKS)
SECRETS = corpus.SECRETS

OSM_XML = """<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6">
  <node id="1" lat="49.980" lon="11.620"/>
  <node id="2" lat="49.981" lon="11.622"/>
  <way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="motorway"/><tag k="name" v="A"/></way>
</osm>
"""


def _dirs(tmp_path: Path) -> corpus.Dirs:
    d = corpus.Dirs(tmp_path)
    d.secret.write_text(corpus.CANARY + "\n", encoding="utf-8")
    return d


def _no_secret(text: str) -> None:
    low = text.lower()
    assert not any(s in low for s in SECRETS), text


def _hostile_xodr(tmp_path: Path, attack: str, name: str = "map.xodr") -> Path:
    d = _dirs(tmp_path)
    xml = XODR.read_text(encoding="utf-8")
    path = tmp_path / name
    path.write_text(
        corpus._hostile_xml(xml, "OpenDRIVE", attack, d, target="geoReference"), encoding="utf-8"
    )
    return path


def _entity_attack(attack: str) -> bool:
    return corpus.XML_ATTACKS[attack] is not None


@pytest.mark.parametrize("attack", ATTACKS)
def test_read_xodr(tmp_path, attack):
    path = _hostile_xodr(tmp_path, attack)
    if _entity_attack(attack):
        with pytest.raises(InputError, match="entit") as err:
            read_xodr(path)
        _no_secret(str(err.value))
    else:  # the xi:include element stays an element: geoReference has no text
        network = read_xodr(path)
        _no_secret(repr(network.header))
        assert network.header.geo_reference == ""


@pytest.mark.parametrize("attack", ATTACKS)
def test_check_file(tmp_path, attack):
    path = _hostile_xodr(tmp_path, attack)
    if _entity_attack(attack):
        with pytest.raises(InputError, match=r"map\.xodr"):
            check_file(path, external=False)
    else:
        report = check_file(path, external=False)
        _no_secret(report.format_text())


@pytest.mark.parametrize("attack", ATTACKS)
def test_load_truth(tmp_path, attack):
    path = _hostile_xodr(tmp_path, attack, name="truth.xodr")
    (tmp_path / "truth.json").write_text('{"ramps": []}', encoding="utf-8")
    if _entity_attack(attack):
        with pytest.raises(InputError, match=r"truth\.xodr"):
            load_truth(path)
    else:
        network, info = load_truth(path)
        _no_secret(repr(network.header))
        assert info == {"ramps": []}


@pytest.mark.parametrize("attack", ATTACKS)
def test_parse_xml_bytes(tmp_path, attack):
    path = _hostile_xodr(tmp_path, attack)
    if _entity_attack(attack):
        with pytest.raises(InputError, match="entit"):
            parse_xml(path.read_bytes(), name="doc")
    else:
        root = parse_xml(path.read_bytes(), name="doc").getroot()
        _no_secret("".join(root.itertext()))


@pytest.mark.parametrize("suffix", [".osm", ".osm.gz", ".osm.bz2"])
@pytest.mark.parametrize("attack", ATTACKS)
def test_load_osm(tmp_path, attack, suffix):
    """libosmium refuses entity declarations and elements inside <tag> itself."""
    d = _dirs(tmp_path)
    xml = corpus._hostile_xml(OSM_XML, "osm", attack, d, target="tag")
    data = xml.encode("utf-8")
    data = {".osm": data, ".osm.gz": gzip.compress(data), ".osm.bz2": bz2.compress(data)}[suffix]
    path = tmp_path / f"map{suffix}"
    path.write_bytes(data)
    frame = MappingFrame(Origin(49.98, 11.62))
    with pytest.raises(InputError, match=r"not a readable OSM file") as err:
        load_osm(path, frame=frame, around_xy=None)
    _no_secret(str(err.value))


@pytest.mark.parametrize("attack", ATTACKS)
def test_crop_osm(tmp_path, attack):
    d = _dirs(tmp_path)
    src = tmp_path / "in.osm"
    src.write_text(corpus._hostile_xml(OSM_XML, "osm", attack, d, target="tag"))
    dst = tmp_path / "out.osm"
    if _entity_attack(attack):
        with pytest.raises(InputError, match="entit"):
            crop_osm(src, dst, bbox=(11.0, 49.0, 12.0, 50.0))
        assert not dst.exists()
    else:
        crop_osm(src, dst, bbox=(11.0, 49.0, 12.0, 50.0))
        _no_secret(dst.read_text())


def test_billion_laughs_is_not_expanded_in_memory(tmp_path):
    """The refusal happens before expansion: 10^9 'LOL's would need gigabytes."""
    import resource

    path = _hostile_xodr(tmp_path, "billion_laughs")
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with pytest.raises(InputError):
        read_xodr(path)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 200_000  # KiB


def test_external_dtd_is_not_loaded(tmp_path):
    """``<!DOCTYPE ... SYSTEM "file">`` names a DTD that is never fetched or read."""
    d = _dirs(tmp_path)
    xml = XODR.read_text(encoding="utf-8").split("?>", 1)[1]
    path = tmp_path / "map.xodr"
    path.write_text(f'<?xml version="1.0"?>\n<!DOCTYPE OpenDRIVE SYSTEM "file://{d.secret}">{xml}')
    shutil.copymode(XODR, path)
    network = read_xodr(path)
    assert network.roads
