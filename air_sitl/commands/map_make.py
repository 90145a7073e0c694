"""``air-sitl map make``: write a procedural map as a Cloud-Optimized GeoTIFF.

The file uses the UTM zone of ``--origin`` and the procedural map's own pixel lattice. With
``--size-m`` the window is centred on ``--origin`` (to the nearest pixel). Without it, the file
is the procedural map's nominal 10240-pixel window: with ``--origin`` equal to a flight's home,
its pixel grid is exactly the grid MapX/MapY count in when flying that procedural map (home
then lies up to 256 pixels south-east of the centre).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

from air_sitl.errors import OptionError
from air_sitl.outdir import add_out_arguments
from air_sitl.state import GeoPoint

HELP = "make map files (map make {urban,forest,farmland} --out FILE.tif)"

DEFAULT_ORIGIN = (54.6872, 25.2797)  # Vilnius, where AIR was made


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``map`` and its ``make`` subcommand."""
    sub = parser.add_subparsers(dest="map_command", metavar="SUBCOMMAND", required=True)
    make = sub.add_parser(
        "make",
        help="write a procedural map as a georeferenced Cloud-Optimized GeoTIFF",
        description="write a procedural map as a georeferenced Cloud-Optimized GeoTIFF",
    )
    make.add_argument("kind", choices=("urban", "forest", "farmland"), help="procedural map")
    make.add_argument("--out", required=True, metavar="FILE.tif", help="output GeoTIFF")
    make.add_argument("--seed", type=int, default=0, help="map seed (default 0)")
    make.add_argument(
        "--size-m",
        type=float,
        nargs=2,
        default=None,
        metavar=("W", "H"),
        help="extent in metres (default 10240 pixels square: 6144 m at 0.6 m)",
    )
    make.add_argument("--gsd-m", type=float, default=0.6, help="metres per pixel (default 0.6)")
    make.add_argument("--date", default=None, help="map date: 0, 1, 2 or its label (default 0)")
    make.add_argument(
        "--origin",
        default=None,
        metavar="LAT,LON",
        help="the flight's home: the centre of a --size-m window; without --size-m, the "
        "procedural map's nominal window around it, in the pixels MapX/MapY count "
        f"(default {DEFAULT_ORIGIN[0]},{DEFAULT_ORIGIN[1]})",
    )
    make.add_argument(
        "--lossless", action="store_true", help="DEFLATE instead of JPEG q90 compression"
    )
    add_out_arguments(make)
    fetch = sub.add_parser(
        "fetch",
        help="mosaic real imagery or elevation from a STAC API or static catalog, one COG per date",
        description="find STAC items over a box and dates, read only the needed windows of "
        "their COG assets, write one COG per acquisition date, DIR/<collection>_<YYYY-MM-DD>.tif "
        "(dated: TIFFTAG_DATETIME and ACQUISITION_DATE; elevation: DIR/dem.tif) and "
        "DIR/fetch.json; --resume into the same DIR continues an interrupted fetch. "
        "Public collections: "
        "--stac https://planetarycomputer.microsoft.com/api/stac/v1 with --collection naip, "
        "3dep-seamless or cop-dem-glo-30 (asset URLs signed with its SAS tokens)",
    )
    # Western longitudes start with '-': let them through as values (-90.2,38.6,...).
    fetch._negative_number_matcher = re.compile(r"^-\d[\d.,-]*$")
    fetch.add_argument("--bbox", required=True, metavar="W,S,E,N", help="degrees")
    fetch.add_argument(
        "--collection", required=True, metavar="ID", help="naip, 3dep, cop-dem-glo-30 or ANY"
    )
    fetch.add_argument(
        "--stac", required=True, metavar="URL_OR_PATH", help="STAC API URL or catalog.json"
    )
    fetch.add_argument(
        "--datetime",
        default=None,
        metavar="START/END",
        help="ISO dates or .. (e.g. 2010-01-01/2022-12-31: one COG per acquisition date)",
    )
    fetch.add_argument("--out", required=True, metavar="DIR", help="output folder")
    fetch.add_argument(
        "--header",
        action="append",
        default=[],
        metavar="'NAME: VALUE'",
        help="an HTTP header sent with every request of the fetch (search, token, assets); "
        "repeatable",
    )
    fetch.add_argument(
        "--token",
        default=None,
        metavar="TOKEN",
        help="same as --header 'Authorization: Bearer TOKEN'",
    )
    fetch.add_argument(
        "--sas-endpoint",
        default=None,
        metavar="URL",
        help="a SAS token endpoint (Planetary Computer's: GET URL/<collection> -> "
        "{'msft:expiry', 'token'}) that signs the asset URLs; default: Planetary Computer's "
        "for its own STAC API, none for others; 'none': unsigned",
    )
    add_out_arguments(
        fetch,
        resume="continue a fetch into --out (same catalog, collection, box and dates): "
        "what is done is kept",
    )


def _parse_origin(text: str | None) -> tuple[float, float]:
    if text is None:
        return DEFAULT_ORIGIN
    try:
        lat_s, lon_s = text.split(",")
        lat, lon = float(lat_s), float(lon_s)
    except ValueError:
        msg = f"--origin {text!r}: expected LAT,LON in degrees"
        raise OptionError(msg) from None
    if not (-80.0 <= lat <= 84.0 and -180.0 <= lon <= 180.0):
        msg = f"--origin {text!r}: outside the UTM domain (latitude -80..84, longitude -180..180)"
        raise OptionError(msg)
    return (lat, lon)


def run(args: argparse.Namespace) -> int:
    """Generate the map window block by block and write it as a COG (or fetch one)."""
    if args.map_command == "fetch":
        return _fetch(args)
    from air_sitl.maps.geotiff import date_tags, write_geotiff
    from air_sitl.maps.procedural import NOMINAL_HALF_PX, ProceduralMap
    from air_sitl.outdir import claim_path
    from air_sitl.progress import Progress

    lat, lon = _parse_origin(args.origin)
    out = Path(args.out)
    if out.suffix.lower() not in (".tif", ".tiff"):
        msg = f"--out {out}: expected a .tif or .tiff file name"
        raise OptionError(msg)
    if not out.parent.is_dir():
        msg = f"--out {out}: folder {out.parent} does not exist"
        raise OptionError(msg)
    claim_path(out, overwrite=args.overwrite)
    gsd = float(args.gsd_m)
    if not (math.isfinite(gsd) and 0.05 <= gsd <= 100.0):
        msg = f"--gsd-m {args.gsd_m}: expected 0.05..100 metres per pixel"
        raise OptionError(msg)
    if args.size_m is None:
        w_px = h_px = 2 * NOMINAL_HALF_PX
    else:
        w_m, h_m = args.size_m
        if not (math.isfinite(w_m) and math.isfinite(h_m) and w_m > 0 and h_m > 0):
            msg = f"--size-m {w_m} {h_m}: expected two positive sizes in metres"
            raise OptionError(msg)
        w_px, h_px = round(w_m / gsd), round(h_m / gsd)
        if w_px < 16 or h_px < 16 or w_px * h_px > 200_000 * 200_000:
            msg = f"--size-m {w_m} {h_m}: {w_px}x{h_px} pixels at {gsd} m is too small or too large"
            raise OptionError(msg)
    home = GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=0.0)
    pmap = ProceduralMap(args.kind, home, seed=args.seed, date=args.date, gsd_m=gsd)
    if args.size_m is None:
        c0 = r0 = 0
    else:
        x, y = pmap.latlon_to_map_px(lat, lon)
        c0, r0 = round(x) - w_px // 2, round(y) - h_px // 2
    t0, t1, t2, t3, t4, t5 = pmap.georef.transform
    transform = (t0 + c0 * t1, t1, t2, t3 + r0 * t5, t4, t5)

    bar = Progress(f"map make {args.kind}", w_px * h_px, unit="px", unit_scale=True)

    def pixels(x0: int, y0: int, w: int, h: int):  # type: ignore[no-untyped-def]
        block = pmap.read_bgr(c0 + x0, r0 + y0, w, h)
        bar.advance(w * h)
        if bar.n >= w_px * h_px:  # the last block: GDAL now compresses and builds overviews
            bar.close()
            print(f"{out}: compressing, building overviews", file=sys.stderr, flush=True)
        return block

    bar.start()  # the rate counts from here, not from the first block's end
    try:
        write_geotiff(
            out,
            pixels,
            width_px=w_px,
            height_px=h_px,
            crs=pmap.georef.crs,
            transform=transform,
            lossless=args.lossless,
            tags=date_tags(pmap.date.label, f"{pmap.date.solar_time}:00"),
        )
    finally:
        bar.close()
    print(
        f"{out}: {args.kind} seed {args.seed} date {pmap.date.label}, {w_px}x{h_px} px at "
        f"{gsd} m, {pmap.georef.crs}",
        file=sys.stdout,
    )
    return 0


def _fetch(args: argparse.Namespace) -> int:
    """``map fetch``: STAC items over a box to one COG per date."""
    from air_sitl.maps.stac import Source, fetch, parse_bbox, parse_datetime, resume_problem
    from air_sitl.maps.stac_http import Http, default_sas_endpoint, parse_header
    from air_sitl.outdir import claim_folder

    stac, collection = str(args.stac), str(args.collection)
    inputs: dict[str, object] = {
        "stac": stac,
        "collection": collection,
        "bbox": list(parse_bbox(str(args.bbox))),
        "datetime": "/".join(parse_datetime(args.datetime)),
    }
    out = Path(args.out)
    headers = [parse_header(str(h)) for h in args.header]
    if args.token:
        headers.append(("Authorization", f"Bearer {args.token}"))
    sas = args.sas_endpoint or default_sas_endpoint(stac)
    source = Source(stac, Http(tuple(headers)), None if sas in (None, "none") else str(sas))
    claim_folder(
        out,
        overwrite=args.overwrite,
        resume=args.resume,
        resume_problem=lambda: resume_problem(out, inputs),
    )
    record = fetch(
        source,
        collection,
        parse_bbox(str(args.bbox)),
        parse_datetime(args.datetime),
        out,
    )
    for name, ids in sorted(record["outputs"].items()):
        when = record["acquired"].get(name)
        dated = f", acquired {when}" if when else ""
        print(f"{Path(args.out) / name}: {len(ids)} item(s){dated}", file=sys.stdout)
    return 0
