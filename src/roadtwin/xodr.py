"""ASAM OpenDRIVE writer and reader for :class:`~roadtwin.model.RoadNetwork`.

Writer
------
:func:`to_xodr_bytes` builds the file through scenariogeneration 0.16.7
(``from scenariogeneration import xodr``), as the paper does: one ``xodr.Road`` per model
road with every planView piece placed explicitly (``PlanView.add_fixed_geometry`` with
the model's start ``x, y, hdg`` and ``s``; the adjust passes ``adjust_roads_and_lanes``,
``adjust_startpoints`` and ``adjust_elevations`` are never called), lane sections, lanes
with all width records (``sOffset``), road marks and lane links, laneOffset, elevation,
superelevation, road links, road type/speed, and junctions (``default`` with
``connectingRoad`` and ``direct`` with ``linkedRoad``) with their lane links.

scenariogeneration cannot express some things exactly, so the element tree it returns is
post-processed with lxml (:func:`_postprocess`):

* ``<userData>``: the header's ``user_data`` pairs (generator, method, self-consistency),
  every road's ``user_data`` pairs and, on every road built from OpenStreetMap,
  ``roadtwin:osm_way_ids`` with its source
  way ids; read back by :func:`read_xodr`.

* ``<header>``: scenariogeneration always writes ``date=datetime.now()`` (not
  deterministic) and zero ``north/south/east/west``; the attributes are rewritten in a
  fixed order (``revMajor``, ``revMinor``, ``name``, ``version``, ``date`` only when
  ``header.date`` is set, ``vendor``). ``<geoReference>`` is written as CDATA (it writes
  plain text) with ``+no_defs`` removed; ``<offset>`` and ``<dataQuality><error>`` have
  no scenariogeneration API and are added with lxml.
* ``<geometry>``: ``s, x, y, hdg, length`` are re-written from the model with
  ``repr(float)`` (shortest round-trip form). scenariogeneration replaces the length of a
  ``normalized`` paramPoly3 by its own numerical arc-length integral; the model's length
  is restored. scenariogeneration has no ``poly3`` geometry: a ``Line`` of the same length
  is placed and its ``<line/>`` child replaced by ``<poly3 a b c d/>``.
* ``<road length>`` is re-written from the model (scenariogeneration sums the pieces).
* ``<laneSection singleSide>``, lane ``type`` (scenariogeneration forces ``none`` on the
  centre lane and its enum lacks some types) and ``level`` are set with lxml.
* ``<laneLink>`` elements of junction connections are re-written in the model's order
  (scenariogeneration sorts them by ``from``), so read -> write -> read is the identity.

Every float is written with ``repr`` (17 significant digits at most, exact round trip),
attribute order is fixed by the construction order, and no timestamp is written unless the
model's header carries one: the same model gives the same bytes. The header declares
OpenDRIVE 1.8 (``revMajor="1" revMinor="8"``, whatever the model's header says); the
output validates against the 1.8 XSD shipped with asam-qc-opendrive (see
:func:`schema_errors`; that XSD is XSD 1.1, which ``lxml.etree.XMLSchema`` cannot load,
so it is checked with ``xmlschema.XMLSchema11`` exactly as the ASAM checker does).

Reader
------
:func:`read_xodr` parses OpenDRIVE 1.4 to 1.8 with lxml (namespaces are ignored; DTDs,
entities and network access off, see :mod:`roadtwin._xml`):
planView ``line, arc, spiral, poly3, paramPoly3`` (``pRange`` ``arcLength`` or
``normalized``, the default when absent), elevation, superelevation, laneOffset, lane
sections with width records, road marks, lane and road links, junctions (``default``,
``direct``; other types are read as ``default``), header with geoReference, offset and
dataQuality. Lanes described by ``<border>`` records instead of ``<width>`` are converted
to widths exactly (difference of consecutive border polynomials) when every lane on that
side uses borders; otherwise an :class:`~roadtwin._errors.InputWarning` is issued and
such lanes get zero width.
"""

from __future__ import annotations

import logging
import math
import os
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

from lxml import etree

from ._errors import InputError, InputWarning, RoadtwinError
from ._files import atomic_write_bytes
from ._perf import gc_paused
from ._xml import parse_xml
from .model import (
    Arc,
    Connection,
    CubicPiece,
    CubicProfile,
    Geometry,
    Header,
    Junction,
    Lane,
    LaneLink,
    LaneSection,
    Line,
    ParamPoly3,
    Poly3,
    Road,
    RoadLink,
    RoadMark,
    RoadNetwork,
    Spiral,
)

log = logging.getLogger(__name__)

__all__ = ["read_xodr", "schema_errors", "to_xodr_bytes", "write_xodr"]


OSM_WAY_IDS_CODE = "roadtwin:osm_way_ids"
"""``<userData code>`` of a road's source OSM way ids (space separated)."""


def _f(value: float) -> str:
    """Fixed float formatting: ``repr`` of a Python float (exact round trip)."""
    v = float(value)
    if v == 0.0:
        return "0.0"  # no "-0.0"
    if math.isnan(v):
        return "NaN"  # the XSD lexical form of xs:double; repr gives "nan"
    return repr(v)


def clean_geo_reference(proj: str) -> str:
    """A PROJ string without ``+no_defs`` (esmini logs an error on it), single-spaced."""
    parts = [p for p in proj.split() if p.strip() and p.strip() != "+no_defs"]
    return " ".join(parts)


# ---------------------------------------------------------------------------
# writer
# ---------------------------------------------------------------------------


def _sg_enum(enum_cls, name: str):
    key = name.replace(" ", "_")
    return enum_cls[key] if key in enum_cls.__members__ else None


def _sg_geometry(g: Geometry, sg):
    if isinstance(g, Arc):
        return sg.Arc(float(g.curvature_per_m), length=float(g.length))
    if isinstance(g, Spiral):
        return sg.Spiral(float(g.curv_start), float(g.curv_end), length=float(g.length))
    if isinstance(g, ParamPoly3):
        return sg.ParamPoly3(
            float(g.aU),
            float(g.bU),
            float(g.cU),
            float(g.dU),
            float(g.aV),
            float(g.bV),
            float(g.cV),
            float(g.dV),
            prange=g.p_range,
            length=float(g.length),
        )
    if isinstance(g, (Line, Poly3)):  # Poly3: placeholder, replaced with lxml
        return sg.Line(float(g.length))
    msg = f"cannot write geometry of type {type(g).__name__}"
    raise InputError(msg)


def _sg_lane(lane: Lane, sg):
    lane_type = _sg_enum(sg.LaneType, lane.type) or sg.LaneType.none
    pieces = lane.width.pieces or (CubicPiece(0.0, 0.0),)
    first = pieces[0]
    out = sg.Lane(
        lane_type,
        float(first.a),
        float(first.b),
        float(first.c),
        float(first.d),
        float(first.s0),
    )
    for p in pieces[1:]:
        out.add_lane_width(float(p.a), float(p.b), float(p.c), float(p.d), float(p.s0))
    if lane.predecessor is not None:
        out.add_link("predecessor", int(lane.predecessor))
    if lane.successor is not None:
        out.add_link("successor", int(lane.successor))
    for mark in lane.road_marks:
        out.add_roadmark(
            sg.RoadMark(
                _sg_enum(sg.RoadMarkType, mark.type) or sg.RoadMarkType.none,
                width=float(mark.width_m),
                soffset=float(mark.s_offset),
                color=_sg_enum(sg.RoadMarkColor, mark.color) or sg.RoadMarkColor.standard,
            )
        )
    return out


def _traffic_rule(road: Road) -> str:
    """``LHT`` when every driving lane of the road is a left lane, else ``RHT``."""
    driving = [
        lane.id
        for sec in road.lane_sections
        for lane in (*sec.left, *sec.right)
        if lane.type == "driving"
    ]
    return "LHT" if driving and all(i > 0 for i in driving) else "RHT"


def _sg_road(road: Road, sg):
    pv = sg.PlanView()
    for g in road.geometry:
        pv.add_fixed_geometry(
            _sg_geometry(g, sg), float(g.x0), float(g.y0), float(g.hdg), s=float(g.s0)
        )
    lanes = sg.Lanes()
    for p in road.lane_offset.pieces:
        lanes.add_laneoffset(
            sg.LaneOffset(float(p.s0), float(p.a), float(p.b), float(p.c), float(p.d))
        )
    for sec in road.lane_sections:
        center = sg.Lane()
        for mark in sec.center.road_marks:
            center.add_roadmark(
                sg.RoadMark(
                    _sg_enum(sg.RoadMarkType, mark.type) or sg.RoadMarkType.none,
                    width=float(mark.width_m),
                    soffset=float(mark.s_offset),
                    color=_sg_enum(sg.RoadMarkColor, mark.color) or sg.RoadMarkColor.standard,
                )
            )
        ls = sg.LaneSection(float(sec.s0), center)
        for lane in sec.left:
            ls.add_left_lane(_sg_lane(lane, sg))
        for lane in sec.right:
            ls.add_right_lane(_sg_lane(lane, sg))
        lanes.add_lanesection(ls)
    rule = sg.TrafficRule.LHT if _traffic_rule(road) == "LHT" else sg.TrafficRule.RHT
    out = sg.Road(road.id, pv, lanes, road_type=road.junction, name=road.name or None, rule=rule)
    road_type = _sg_enum(sg.RoadType, road.road_type)
    if road_type is not None:
        speed = None if road.speed_limit_mps is None else float(road.speed_limit_mps)
        out.add_type(road_type, 0.0, None, speed, "m/s")
    for link, add in ((road.predecessor, out.add_predecessor), (road.successor, out.add_successor)):
        if link is None:
            continue
        etype = sg.ElementType.road if link.element_type == "road" else sg.ElementType.junction
        cp = None
        if link.contact_point is not None:
            cp = sg.ContactPoint.start if link.contact_point == "start" else sg.ContactPoint.end
        add(etype, link.element_id, cp)
    for p in road.elevation.pieces:
        out.add_elevation(float(p.s0), float(p.a), float(p.b), float(p.c), float(p.d))
    if road.superelevation is not None:
        for p in road.superelevation.pieces:
            out.add_superelevation(float(p.s0), float(p.a), float(p.b), float(p.c), float(p.d))
    return out


def _sg_junction(junction: Junction, sg):
    jtype = sg.JunctionType.direct if junction.type == "direct" else sg.JunctionType.default
    out = sg.Junction(junction.name, junction.id, jtype)
    for con in junction.connections:
        cp = sg.ContactPoint.start if con.contact_point == "start" else sg.ContactPoint.end
        c = sg.Connection(con.incoming_road, con.connecting_road, cp, id=con.id)
        for ll in con.lane_links:
            c.add_lanelink(int(ll.from_lane), int(ll.to_lane))
        out.add_connection(c)
    return out


def _set_attrs(el: etree._Element, items: Sequence[tuple[str, str]]) -> None:
    """Replace all attributes of ``el`` by ``items`` in that order."""
    el.attrib.clear()
    for key, value in items:
        el.set(key, value)


def _postprocess(root: etree._Element, network: RoadNetwork) -> None:
    """Fix what scenariogeneration cannot express (see the module docstring)."""
    hdr = network.header
    header = root.find("header")
    attrs = [("revMajor", "1"), ("revMinor", "8"), ("name", hdr.name)]
    if hdr.date:
        attrs.append(("date", hdr.date))
    attrs.append(("vendor", hdr.vendor))
    _set_attrs(header, attrs)
    for child in list(header):
        header.remove(child)
    if hdr.geo_reference:
        geo = etree.SubElement(header, "geoReference")
        geo.text = etree.CDATA(clean_geo_reference(hdr.geo_reference))
    if hdr.offset is not None:
        x, y, z, h = hdr.offset
        etree.SubElement(header, "offset", x=_f(x), y=_f(y), z=_f(z), hdg=_f(h))
    if hdr.data_quality:
        dq = etree.SubElement(header, "dataQuality")
        q = hdr.data_quality
        etree.SubElement(
            dq,
            "error",
            xyAbsolute=_f(q.get("xy_absolute", math.nan)),
            xyRelative=_f(q.get("xy_relative", math.nan)),
            zAbsolute=_f(q.get("z_absolute", math.nan)),
            zRelative=_f(q.get("z_relative", math.nan)),
        )
    for code, value in hdr.user_data:
        etree.SubElement(header, "userData", code=code, value=value)
    road_elements = root.findall("road")
    for road, el in zip(network.roads, road_elements, strict=False):
        el.set("length", _f(road.length))
        if road.osm_way_ids:
            etree.SubElement(
                el,
                "userData",
                code=OSM_WAY_IDS_CODE,
                value=" ".join(str(w) for w in road.osm_way_ids),
            )
        for code, value in road.user_data:
            etree.SubElement(el, "userData", code=code, value=value)
        geoms = el.find("planView").findall("geometry")
        for g, gel in zip(road.geometry, geoms, strict=False):
            _set_attrs(
                gel,
                [
                    ("s", _f(g.s0)),
                    ("x", _f(g.x0)),
                    ("y", _f(g.y0)),
                    ("hdg", _f(g.hdg)),
                    ("length", _f(g.length)),
                ],
            )
            if isinstance(g, Poly3):
                for child in list(gel):
                    gel.remove(child)
                etree.SubElement(gel, "poly3", a=_f(g.a), b=_f(g.b), c=_f(g.c), d=_f(g.d))
        sec_elements = el.find("lanes").findall("laneSection")
        for sec, sel in zip(road.lane_sections, sec_elements, strict=False):
            if sec.single_side:
                sel.set("singleSide", "true")
            lane_els = {int(le.get("id")): le for le in sel.iter("lane")}
            for lane in sec.lanes:
                le = lane_els.get(lane.id)
                if le is None:
                    continue
                le.set("type", lane.type)
                le.set("level", "true" if lane.level else "false")
    for junction, jel in zip(network.junctions, root.findall("junction"), strict=False):
        for con, cel in zip(junction.connections, jel.findall("connection"), strict=False):
            for ll_el in cel.findall("laneLink"):
                cel.remove(ll_el)
            for ll in con.lane_links:  # model order (scenariogeneration sorts by "from")
                etree.SubElement(
                    cel, "laneLink", {"from": str(ll.from_lane), "to": str(ll.to_lane)}
                )


def to_xodr_bytes(network: RoadNetwork) -> bytes:
    """Serialise ``network`` as OpenDRIVE 1.8 XML (UTF-8 bytes, deterministic).

    Parameters
    ----------
    network
        The road network (mapping frame, metres, radians).

    Returns
    -------
    bytes
        The complete ``.xodr`` document, pretty-printed.
    """
    from ._lazy import bind_lazily

    # scenariogeneration imports xmlschema (0.16 s) for reading OpenSCENARIO files,
    # which writing a map never does
    bind_lazily("xmlschema")
    from scenariogeneration import xodr as sg

    if not network.roads:
        msg = "cannot write an OpenDRIVE file without roads"
        raise InputError(msg)
    for road in network.roads:
        if not road.lane_sections or not road.geometry:
            msg = f"road {road.id}: OpenDRIVE needs at least one geometry piece and lane section"
            raise InputError(msg)
    odr = sg.OpenDrive(network.header.name, revMajor="1", revMinor="8")
    for road in network.roads:
        odr.add_road(_sg_road(road, sg))
    for junction in network.junctions:
        odr.add_junction(_sg_junction(junction, sg))
    root = etree.fromstring(ET.tostring(odr.get_element()))
    _postprocess(root, network)
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def write_xodr(network: RoadNetwork, path: str | os.PathLike) -> Path:
    """Write ``network`` to ``path`` atomically (temporary file in the same folder, then
    ``os.replace``; ordinary file mode). Returns the path."""
    path = atomic_write_bytes(path, to_xodr_bytes(network))
    log.info("wrote %s: %d roads, %d junctions", path, len(network.roads), len(network.junctions))
    return path


def _schema_file(rev_minor: int) -> Path:
    try:
        import qc_opendrive
    except ImportError:
        msg = (
            "schema validation needs the OpenDRIVE XSD of the ASAM quality checker: "
            'pip install "roadtwin[validate]"'
        )
        raise RoadtwinError(msg) from None

    base = Path(qc_opendrive.__file__).parent / "schema"
    candidates = {
        8: base / "1.8.0" / "OpenDRIVE_Core.xsd",
        6: base / "1.6.1" / "opendrive_16_core.xsd",
    }
    path = candidates.get(rev_minor)
    if path is None or not path.is_file():
        msg = f"no OpenDRIVE 1.{rev_minor} schema found under {base}"
        raise InputError(msg)
    return path


@lru_cache(maxsize=4)
def _schema(rev_minor: int):
    path = _schema_file(rev_minor)
    if rev_minor >= 8:  # the 1.8 XSD is XSD 1.1: lxml (XSD 1.0 only) cannot load it
        import xmlschema

        return xmlschema.XMLSchema11(str(path))
    return etree.XMLSchema(etree.parse(str(path)))


def schema_errors(data: bytes | str | os.PathLike, *, rev_minor: int = 8) -> list[str]:
    """Validate an OpenDRIVE document against the XSD shipped with asam-qc-opendrive.

    The 1.8 schema is XSD 1.1 and is checked with ``xmlschema`` (as the ASAM checker
    does); the 1.6 schema with ``lxml.etree.XMLSchema``.

    Parameters
    ----------
    data
        The document as bytes, or a file path.

    Returns
    -------
    list of str
        One ``"line N: reason"`` per violation; empty when valid.
    """
    doc = parse_xml(data if isinstance(data, bytes) else Path(data))
    schema = _schema(rev_minor)
    if isinstance(schema, etree.XMLSchema):
        schema.validate(doc)
        return [f"line {e.line}: {e.message}" for e in schema.error_log]
    return [f"line {e.sourceline}: {e.reason}" for e in schema.iter_errors(doc)]


# ---------------------------------------------------------------------------
# reader
# ---------------------------------------------------------------------------


_MAX_COORDINATE_M = 1.0e8
"""Largest absolute station, coordinate or length (metres) a map may hold: no place on
earth is farther from a projected CRS's origin (as ``pointfiles.MAX_COORDINATE_M``)."""


_MAX_COEFFICIENT = 1.0e15
"""Largest absolute b, c, d of a cubic profile: a 1 mm width piece needs ~1e10; larger values
overflow when the profile is evaluated over a road's length."""


def _num(
    el: etree._Element,
    key: str,
    default: float | None = None,
    *,
    where: str = "",
    finite: bool = True,
    limit: float | None = None,
) -> float:
    """A numeric attribute; refused when missing (without default), not a number,
    non-finite (unless ``finite=False``) or beyond ``limit`` in absolute value."""
    raw = el.get(key)
    if raw is None:
        if default is None:
            msg = f"{where}: <{el.tag}> line {el.sourceline} lacks attribute {key!r}"
            raise InputError(msg)
        return default
    try:
        value = float(raw)
    except ValueError:
        msg = f"{where}: <{el.tag}> line {el.sourceline}: attribute {key} is not a number"
        raise InputError(msg) from None
    if finite and not math.isfinite(value):
        msg = (
            f"{where}: <{el.tag}> line {el.sourceline}: attribute {key} is {value} "
            "(expected a finite number)"
        )
        raise InputError(msg)
    if limit is not None and abs(value) > limit:
        msg = (
            f"{where}: <{el.tag}> line {el.sourceline}: attribute {key} = {value:.3g} is beyond "
            f"{limit:.0e} m (no road is that long or that far from the CRS origin)"
        )
        raise InputError(msg)
    return value


def _cubic_pieces(els, s_key: str, *, where: str) -> tuple[CubicPiece, ...]:
    pieces = [
        CubicPiece(
            _num(e, s_key, 0.0, where=where, limit=_MAX_COORDINATE_M),
            _num(e, "a", 0.0, where=where, limit=_MAX_COORDINATE_M),
            _num(e, "b", 0.0, where=where, limit=_MAX_COEFFICIENT),
            _num(e, "c", 0.0, where=where, limit=_MAX_COEFFICIENT),
            _num(e, "d", 0.0, where=where, limit=_MAX_COEFFICIENT),
        )
        for e in els
    ]
    pieces.sort(key=lambda p: p.s0)
    return tuple(pieces)


def _shift_cubic(p: CubicPiece, s_new: float) -> CubicPiece:
    """The same cubic re-expanded around ``s_new`` (exact)."""
    h = s_new - p.s0
    a = p.a + h * (p.b + h * (p.c + h * p.d))
    b = p.b + h * (2 * p.c + 3 * h * p.d)
    c = p.c + 3 * h * p.d
    return CubicPiece(s_new, a, b, c, p.d)


def _profile_minus(outer: CubicProfile, inner: CubicProfile) -> CubicProfile:
    """``outer - inner`` as one piecewise cubic (breakpoints = union of both)."""
    s_all = sorted({p.s0 for p in outer.pieces} | {p.s0 for p in inner.pieces})
    out = []
    for s in s_all:
        po = _active(outer, s)
        pi = _active(inner, s)
        a = _shift_cubic(po, s) if po else CubicPiece(s, 0.0)
        b = _shift_cubic(pi, s) if pi else CubicPiece(s, 0.0)
        out.append(CubicPiece(s, a.a - b.a, a.b - b.b, a.c - b.c, a.d - b.d))
    return CubicProfile(tuple(out))


def _active(profile: CubicProfile, s: float) -> CubicPiece | None:
    if not profile.pieces:
        return None
    best = profile.pieces[0]
    for p in profile.pieces:
        if p.s0 <= s:
            best = p
    return best


def _read_geometry(gel: etree._Element, *, where: str) -> Geometry | None:
    s = _num(gel, "s", where=where, limit=_MAX_COORDINATE_M)
    x = _num(gel, "x", where=where, limit=_MAX_COORDINATE_M)
    y = _num(gel, "y", where=where, limit=_MAX_COORDINATE_M)
    hdg = _num(gel, "hdg", where=where, limit=1e6)
    length = _num(gel, "length", where=where, limit=_MAX_COORDINATE_M)
    if length < 0:
        msg = f"{where}: <geometry> line {gel.sourceline}: attribute length is negative"
        raise InputError(msg)
    kinds = [c for c in gel if isinstance(c.tag, str)]
    if not kinds:
        msg = f"{where}: <geometry> line {gel.sourceline} has no line/arc/spiral/poly3 child"
        raise InputError(msg)
    k = kinds[0]
    tag = etree.QName(k).localname
    if tag == "line":
        return Line(s, x, y, hdg, length)
    if tag == "arc":
        return Arc(s, x, y, hdg, length, _num(k, "curvature", where=where))
    if tag == "spiral":
        return Spiral(
            s, x, y, hdg, length, _num(k, "curvStart", where=where), _num(k, "curvEnd", where=where)
        )
    if tag == "poly3":
        return Poly3(
            s,
            x,
            y,
            hdg,
            length,
            *(_num(k, c, 0.0, where=where) for c in "abcd"),
        )
    if tag == "paramPoly3":
        p_range = k.get("pRange", "normalized")
        if p_range not in ("arcLength", "normalized"):
            msg = f"{where}: paramPoly3 line {k.sourceline}: unknown pRange {p_range!r}"
            raise InputError(msg)
        coeffs = [
            _num(k, c, 0.0, where=where) for c in ("aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV")
        ]
        return ParamPoly3(s, x, y, hdg, length, *coeffs, p_range=p_range)
    msg = f"{where}: unknown geometry <{tag}> at line {k.sourceline}"
    raise InputError(msg)


def _read_lane(le: etree._Element, *, where: str) -> tuple[Lane, tuple[CubicPiece, ...]]:
    lane_id = int(_num(le, "id", where=where))
    width = _cubic_pieces(le.findall("width"), "sOffset", where=where)
    border = _cubic_pieces(le.findall("border"), "sOffset", where=where)
    marks = tuple(
        RoadMark(
            _num(m, "sOffset", 0.0, where=where),
            m.get("type", "none"),  # type: ignore[arg-type]
            _num(m, "width", 0.15, where=where),
            m.get("color", "standard"),
        )
        for m in le.findall("roadMark")
    )
    link = le.find("link")
    pred = succ = None
    if link is not None:
        p = link.find("predecessor")
        q = link.find("successor")
        pred = int(_num(p, "id", where=where)) if p is not None else None
        succ = int(_num(q, "id", where=where)) if q is not None else None
    lane = Lane(
        lane_id,
        le.get("type", "none"),  # type: ignore[arg-type]
        CubicProfile(width),
        marks,
        pred,
        succ,
        le.get("level", "false") in ("true", "1"),
    )
    return lane, border


def _side_from_borders(
    items: list[tuple[Lane, tuple[CubicPiece, ...]]], *, where: str, s0: float
) -> tuple[Lane, ...]:
    """Lanes of one side (inner to outer); border records converted to widths."""
    from dataclasses import replace

    uses_border = [bool(b) and not lane.width.pieces for lane, b in items]
    if not any(uses_border):
        return tuple(lane for lane, _ in items)
    if all(uses_border):
        out = []
        previous = CubicProfile()
        for lane, border in items:
            bprof = CubicProfile(border)
            sign = 1.0 if lane.id > 0 else -1.0
            diff = _profile_minus(bprof, previous)
            diff = CubicProfile(
                tuple(
                    CubicPiece(p.s0, sign * p.a, sign * p.b, sign * p.c, sign * p.d)
                    for p in diff.pieces
                )
            )
            out.append(replace(lane, width=diff))
            previous = bprof
        return tuple(out)
    warnings.warn(
        f"{where}: lane section at s={s0}: lanes mix <border> and <width> records; "
        "lanes with only <border> get zero width",
        InputWarning,
        stacklevel=4,
    )
    return tuple(lane for lane, _ in items)


def _read_road_link(el: etree._Element | None, *, where: str) -> RoadLink | None:
    if el is None:
        return None
    etype = el.get("elementType", "road")
    eid = el.get("elementId")
    if eid is None:
        msg = f"{where}: road link at line {el.sourceline} lacks elementId"
        raise InputError(msg)
    cp = el.get("contactPoint")
    if etype not in ("road", "junction"):
        return None
    return RoadLink(etype, eid, cp if cp in ("start", "end") else None)  # type: ignore[arg-type]


_SPEED_TO_MPS = {"m/s": 1.0, "km/h": 1.0 / 3.6, "mph": 0.44704}


def _read_road(rel: etree._Element, *, where: str) -> Road:
    rid = rel.get("id")
    if rid is None:
        msg = f"{where}: <road> at line {rel.sourceline} has no id"
        raise InputError(msg)
    here = f"{where}: road {rid}"
    pv = rel.find("planView")
    if pv is None:
        msg = f"{here}: no <planView>"
        raise InputError(msg)
    geometry = tuple(
        sorted((_read_geometry(g, where=here) for g in pv.findall("geometry")), key=lambda g: g.s0)
    )
    if not geometry:
        msg = f"{here}: <planView> has no <geometry>"
        raise InputError(msg)
    link = rel.find("link")
    pred = succ = None
    if link is not None:
        pred = _read_road_link(link.find("predecessor"), where=here)
        succ = _read_road_link(link.find("successor"), where=here)
    ep = rel.find("elevationProfile")
    elevation = CubicProfile(
        _cubic_pieces(ep.findall("elevation"), "s", where=here) if ep is not None else ()
    )
    lp = rel.find("lateralProfile")
    superelevation = None
    if lp is not None and lp.find("superelevation") is not None:
        superelevation = CubicProfile(_cubic_pieces(lp.findall("superelevation"), "s", where=here))
    lanes_el = rel.find("lanes")
    lane_offset = CubicProfile()
    sections: list[LaneSection] = []
    if lanes_el is not None:
        lane_offset = CubicProfile(_cubic_pieces(lanes_el.findall("laneOffset"), "s", where=here))
        for sel in lanes_el.findall("laneSection"):
            s0 = _num(sel, "s", 0.0, where=here)
            left_items = [_read_lane(le, where=here) for le in sel.findall("left/lane")]
            right_items = [_read_lane(le, where=here) for le in sel.findall("right/lane")]
            center_el = sel.find("center/lane")
            center = _read_lane(center_el, where=here)[0] if center_el is not None else Lane(0)
            left_items.sort(key=lambda item: item[0].id)
            right_items.sort(key=lambda item: -item[0].id)
            sections.append(
                LaneSection(
                    s0,
                    _side_from_borders(left_items, where=here, s0=s0),
                    center,
                    _side_from_borders(right_items, where=here, s0=s0),
                    sel.get("singleSide", "false") in ("true", "1"),
                )
            )
    sections.sort(key=lambda sec: sec.s0)
    type_el = rel.find("type")
    road_type, speed = "unknown", None
    if type_el is not None:
        road_type = type_el.get("type", "unknown")
        sp = type_el.find("speed")
        if sp is not None and sp.get("max") not in (None, "no limit", "undefined"):
            try:
                speed = float(sp.get("max")) * _SPEED_TO_MPS.get(sp.get("unit", "m/s"), 1.0)
            except ValueError:
                speed = None
    _num(rel, "length", 0.0, where=where, limit=_MAX_COORDINATE_M)  # validated, not stored
    return Road(
        id=rid,
        geometry=geometry,
        lane_sections=tuple(sections),
        name=rel.get("name", ""),
        elevation=elevation,
        superelevation=superelevation,
        lane_offset=lane_offset,
        predecessor=pred,
        successor=succ,
        junction=rel.get("junction", "-1"),
        road_type=road_type,
        speed_limit_mps=speed,
        osm_way_ids=_osm_way_ids(rel, where=where),
        user_data=tuple(
            (u.get("code", ""), u.get("value", ""))
            for u in rel.findall("userData")
            # only roadtwin's own pairs: other tools' userData may hold nested content
            if (u.get("code") or "").startswith("roadtwin:") and u.get("code") != OSM_WAY_IDS_CODE
        ),
    )


def _osm_way_ids(rel: etree._Element, *, where: str) -> tuple[int, ...]:
    for u in rel.findall("userData"):
        if u.get("code") == OSM_WAY_IDS_CODE:
            try:
                return tuple(int(w) for w in (u.get("value") or "").split())
            except ValueError:
                msg = f"{where}: <userData> line {u.sourceline}: OSM way ids are not integers"
                raise InputError(msg) from None
    return ()


def _read_junction(jel: etree._Element, *, where: str) -> Junction:
    jid = jel.get("id")
    if jid is None:
        msg = f"{where}: <junction> at line {jel.sourceline} has no id"
        raise InputError(msg)
    jtype = jel.get("type", "default")
    if jtype not in ("default", "direct"):
        log.info("%s: junction %s of type %r read as default", where, jid, jtype)
        jtype = "default"
    connections = []
    for cel in jel.findall("connection"):
        target = cel.get("connectingRoad") or cel.get("linkedRoad")
        incoming = cel.get("incomingRoad")
        if target is None or incoming is None:
            log.info("%s: junction %s: connection without roads skipped", where, jid)
            continue
        lane_links = tuple(
            LaneLink(int(_num(ll, "from", where=where)), int(_num(ll, "to", where=where)))
            for ll in cel.findall("laneLink")
        )
        cp = cel.get("contactPoint", "start")
        connections.append(
            Connection(
                cel.get("id", str(len(connections))),
                incoming,
                target,
                cp if cp in ("start", "end") else "start",  # type: ignore[arg-type]
                lane_links,
            )
        )
    return Junction(jid, tuple(connections), jel.get("name", ""), jtype)  # type: ignore[arg-type]


def _read_header(hel: etree._Element | None, *, where: str) -> Header:
    if hel is None:
        msg = f"{where}: no <header>"
        raise InputError(msg)
    geo = hel.find("geoReference")
    geo_text = (geo.text or "").strip() if geo is not None else ""
    off = hel.find("offset")
    offset = None
    if off is not None:
        offset = tuple(_num(off, k, 0.0, where=where) for k in ("x", "y", "z", "hdg"))
    dq = hel.find("dataQuality/error")
    quality = None
    if dq is not None:
        quality = {}
        for key, attr in (
            ("xy_absolute", "xyAbsolute"),
            ("xy_relative", "xyRelative"),
            ("z_absolute", "zAbsolute"),
            ("z_relative", "zRelative"),
        ):
            v = _num(dq, attr, math.nan, where=where, finite=False)
            if not math.isnan(v):
                quality[key] = v
    user_data = tuple((u.get("code", ""), u.get("value", "")) for u in hel.findall("userData"))
    return Header(
        user_data=user_data,
        name=hel.get("name", ""),
        rev_major=int(_num(hel, "revMajor", 1.0, where=where)),
        rev_minor=int(_num(hel, "revMinor", 4.0, where=where)),
        geo_reference=geo_text,
        offset=offset,  # type: ignore[arg-type]
        vendor=hel.get("vendor", ""),
        date=hel.get("date", ""),
        data_quality=quality,
    )


def _strip_namespaces(root: etree._Element) -> None:
    for el in root.iter():
        if isinstance(el.tag, str) and el.tag.startswith("{"):
            el.tag = etree.QName(el).localname


MAX_XODR_BYTES = 32 * 1024 * 1024
"""Largest map file :func:`read_xodr` reads by default (32 MiB, about 20,000 simple roads;
the 2 km demo map is 0.1 MiB). Reading, checking and evaluating cost about 0.5, 0.8 and
1.5 ms and 40 KB of memory per road, linear in size (``benchmarks/bench_limits.py``), so
``check`` and ``evaluate`` finish a 32 MiB map within a minute on a 2-core machine; larger
maps are refused with this reason rather than running for minutes (``max_bytes=None``
lifts the limit in Python)."""
MAX_GEOMETRIES = 500_000
"""Largest number of planView pieces :func:`read_xodr` reads by default (a map of
1 mm pieces can pack more into 32 MiB than any real map has)."""


def read_xodr(
    path: str | os.PathLike,
    *,
    max_bytes: int | None = MAX_XODR_BYTES,
    max_geometries: int | None = MAX_GEOMETRIES,
) -> RoadNetwork:
    """Read an OpenDRIVE 1.4-1.8 file into a :class:`RoadNetwork`.

    Parameters
    ----------
    path
        ``.xodr`` file.

    Returns
    -------
    RoadNetwork
        Roads, junctions and header; coordinates exactly as in the file (the file's
        inertial frame, metres, radians; ``header.offset`` is stored, not applied).

    Raises
    ------
    InputError
        The file is missing, not XML, not OpenDRIVE, lacks required attributes, holds
        non-finite or out-of-range numbers, or is larger than ``max_bytes`` /
        ``max_geometries`` (:data:`MAX_XODR_BYTES`, :data:`MAX_GEOMETRIES`; None: no limit).
    """
    path = Path(path)
    if not path.is_file():
        what = "not a file" if path.exists() else "file not found"
        msg = f"{path}: {what}"
        raise InputError(msg)
    size = path.stat().st_size
    if max_bytes is not None and size > max_bytes:
        msg = (
            f"{path}: {size / 2**20:.0f} MiB; maps larger than {max_bytes / 2**20:.0f} MiB "
            "are refused (roadtwin.xodr.MAX_XODR_BYTES: about 20,000 roads, checked and "
            "evaluated within a minute): split the map"
        )
        raise InputError(msg)
    with gc_paused():
        root = parse_xml(path).getroot()
        if max_geometries is not None:
            pieces = int(root.xpath("count(//*[local-name()='geometry'])"))
            if pieces > max_geometries:
                msg = (
                    f"{path}: {pieces:,} planView pieces; maps with more than "
                    f"{max_geometries:,} are refused (roadtwin.xodr.MAX_GEOMETRIES)"
                )
                raise InputError(msg)
        return _read_root(root, path)


def _read_root(root: etree._Element, path: Path) -> RoadNetwork:
    _strip_namespaces(root)
    if root.tag != "OpenDRIVE":
        msg = f"{path}: root element is <{root.tag}>, expected <OpenDRIVE>"
        raise InputError(msg)
    where = str(path)
    header = _read_header(root.find("header"), where=where)
    roads = tuple(_read_road(rel, where=where) for rel in root.findall("road"))
    if not roads:
        msg = f"{path}: OpenDRIVE file has no <road>"
        raise InputError(msg)
    junctions = tuple(_read_junction(jel, where=where) for jel in root.findall("junction"))
    log.info("read %s: %d roads, %d junctions", path, len(roads), len(junctions))
    return RoadNetwork(header, roads, junctions)
