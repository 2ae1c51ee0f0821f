"""Size limits: ``check`` and ``evaluate`` on huge maps must stay linear (issue 13).

Writes two synthetic OpenDRIVE maps and times ``roadtwin check --no-external`` (and the
reader alone) on them at several sizes, so the growth is visible:

* ``roads``: N straight roads of 20 m (2 lanes each side), chained by predecessor /
  successor links -- at N = 120,000 the file is about 200 MB;
* ``pieces``: one road whose reference line is M line pieces of 1 mm -- at M = 10^6.

    python benchmarks/bench_limits.py [--roads 12000 24000 120000] [--pieces 100000 1000000]
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

HEADER = (
    '<?xml version="1.0" encoding="UTF-8"?>\n<OpenDRIVE>\n'
    '  <header revMajor="1" revMinor="8" name="big" vendor="bench">\n'
    "    <geoReference><![CDATA[+proj=tmerc +lat_0=49.98 +lon_0=11.62 +k=1 +x_0=0 +y_0=0 "
    "+ellps=WGS84 +units=m]]></geoReference>\n  </header>\n"
)


def _lane(lane_id: int) -> str:
    return (
        f'          <lane id="{lane_id}" type="driving" level="false"><link/>'
        '<width sOffset="0.0" a="3.5" b="0.0" c="0.0" d="0.0"/>'
        '<roadMark sOffset="0.0" type="solid" weight="standard" color="standard" width="0.15"/>'
        "</lane>\n"
    )


def _road_ref(road_id: int) -> str:
    return f'elementType="road" elementId="{road_id}"'


def write_roads(path: Path, n: int, length_m: float = 20.0) -> None:
    """N chained straight roads along +x (rows of 1000 roads, 100 m apart)."""
    with path.open("w", encoding="utf-8") as fh:
        fh.write(HEADER)
        for i in range(n):
            row, col = divmod(i, 1000)
            x, y = col * length_m, row * 100.0
            links = []
            if col > 0:
                links.append(f'<predecessor {_road_ref(i - 1)} contactPoint="end"/>')
            if col < 999 and i + 1 < n:
                links.append(f'<successor {_road_ref(i + 1)} contactPoint="start"/>')
            fh.write(
                f'  <road name="r{i}" length="{length_m}" id="{i}" junction="-1">\n'
                f"    <link>{''.join(links)}</link>\n"
                f'    <planView><geometry s="0.0" x="{x}" y="{y}" hdg="0.0" length="{length_m}">'
                "<line/></geometry></planView>\n"
                '    <elevationProfile><elevation s="0.0" a="0.0" b="0.0" c="0.0" d="0.0"/>'
                "</elevationProfile>\n"
                '    <lanes><laneSection s="0.0">\n'
                "        <left>\n" + _lane(2) + _lane(1) + "        </left>\n"
                '        <center><lane id="0" type="none" level="false"/></center>\n'
                "        <right>\n" + _lane(-1) + _lane(-2) + "        </right>\n"
                "    </laneSection></lanes>\n  </road>\n"
            )
        fh.write("</OpenDRIVE>\n")


def write_pieces(path: Path, m: int, piece_m: float = 0.001) -> None:
    """One straight road of M line pieces of ``piece_m`` metres."""
    with path.open("w", encoding="utf-8") as fh:
        fh.write(HEADER)
        fh.write(f'  <road name="long" length="{m * piece_m}" id="1" junction="-1">\n')
        fh.write("    <link/>\n    <planView>\n")
        for k in range(m):
            s = k * piece_m
            fh.write(
                f'      <geometry s="{s!r}" x="{s!r}" y="0.0" hdg="0.0" length="{piece_m}">'
                "<line/></geometry>\n"
            )
        fh.write('    </planView>\n    <lanes><laneSection s="0.0">\n')
        fh.write('        <center><lane id="0" type="none" level="false"/></center>\n')
        fh.write("        <right>\n" + _lane(-1) + "        </right>\n")
        fh.write("    </laneSection></lanes>\n  </road>\n</OpenDRIVE>\n")


def _time(label: str, path: Path) -> None:
    from roadtwin.check import check_file
    from roadtwin.xodr import read_xodr

    t0 = time.perf_counter()
    network = read_xodr(path)
    t1 = time.perf_counter()
    report = check_file(path, external=False)
    t2 = time.perf_counter()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"{label:<24} {path.stat().st_size / 1e6:8.1f} MB  read {t1 - t0:7.2f} s  "
        f"check {t2 - t1:7.2f} s  ({len(network.roads)} roads, {report.errors} errors, "
        f"peak RSS {peak:.0f} MiB)"
    )
    sys.stdout.flush()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--roads", type=int, nargs="*", default=[12_000, 24_000, 120_000])
    parser.add_argument("--pieces", type=int, nargs="*", default=[100_000, 200_000, 1_000_000])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="roadtwin-limits-") as tmp:
        for n in args.roads:
            path = Path(tmp) / f"roads_{n}.xodr"
            write_roads(path, n)
            _time(f"{n:,} roads", path)
            path.unlink()
        for m in args.pieces:
            path = Path(tmp) / f"pieces_{m}.xodr"
            write_pieces(path, m)
            _time(f"1 road of {m:,} pieces", path)
            path.unlink()


if __name__ == "__main__":
    main()
