"""``air-sitl render``: one camera frame of a map at a pose (preview a map, check a mounting)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from air_sitl.camera.options import (
    add_camera_arguments,
    add_map_arguments,
    camera_from_args,
    map_choice_from_args,
    open_chosen_renderer,
)
from air_sitl.errors import OptionError
from air_sitl.state import GeoPoint

HELP = "render one camera frame of a map at a pose to a JPEG (or PNG) file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``render``."""
    parser.add_argument("--lat", type=float, required=True, help="latitude, degrees")
    parser.add_argument("--lon", type=float, required=True, help="longitude, degrees")
    parser.add_argument(
        "--alt-agl",
        type=float,
        default=None,
        metavar="H",
        help="height above the ground (with --dem: above the surface under the camera), m",
    )
    parser.add_argument(
        "--alt-amsl",
        type=float,
        default=None,
        metavar="H",
        help="the camera's altitude above mean sea level, m (instead of --alt-agl)",
    )
    parser.add_argument(
        "--ground-alt-m", type=float, default=0.0, help="ground elevation AMSL (default 0)"
    )
    parser.add_argument("--roll", type=float, default=0.0, metavar="DEG")
    parser.add_argument("--pitch", type=float, default=0.0, metavar="DEG")
    parser.add_argument("--yaw", type=float, default=0.0, metavar="DEG", help="heading")
    parser.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    parser.add_argument("--frame-index", type=int, default=0, help="frame index for the noise")
    parser.add_argument("--out", required=True, metavar="FILE", help="output .jpg or .png")
    add_map_arguments(parser)
    add_camera_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Render and write the frame; print where its centre falls on the map."""
    import cv2

    from air_sitl.camera.render import pose_state
    from air_sitl.files import write_bytes_atomic
    from air_sitl.maps.choose import open_chosen_map

    out = Path(args.out)
    if out.suffix.lower() not in (".jpg", ".jpeg", ".png"):
        msg = f"--out {out}: expected a .jpg, .jpeg or .png file name"
        raise OptionError(msg)
    if not out.parent.is_dir():
        msg = f"--out {out}: folder {out.parent} does not exist"
        raise OptionError(msg)
    if not (-90.0 <= args.lat <= 90.0 and -180.0 <= args.lon <= 180.0):
        msg = f"--lat/--lon {args.lat}, {args.lon}: outside [-90, 90] x [-180, 180]"
        raise OptionError(msg)
    if (args.alt_agl is None) == (args.alt_amsl is None):
        msg = "--alt-agl / --alt-amsl: give exactly one of the two"
        raise OptionError(msg)
    if args.alt_agl is not None and not (math.isfinite(args.alt_agl) and args.alt_agl > 0.0):
        msg = f"--alt-agl {args.alt_agl}: expected a height above ground > 0 m"
        raise OptionError(msg)
    if args.alt_amsl is not None and not math.isfinite(args.alt_amsl):
        msg = f"--alt-amsl {args.alt_amsl}: expected a finite altitude in metres"
        raise OptionError(msg)
    home = GeoPoint(lat_deg=args.lat, lon_deg=args.lon, alt_amsl_m=args.ground_alt_m)
    camera = camera_from_args(args)
    choice = map_choice_from_args(args)
    map_source = open_chosen_map(choice, home)
    renderer = open_chosen_renderer(choice, map_source, camera, args.seed)
    surface = renderer.surface
    ground = args.ground_alt_m if surface is None else surface.height_at(args.lat, args.lon)
    alt_amsl = args.alt_amsl if args.alt_amsl is not None else ground + args.alt_agl
    if alt_amsl <= ground:
        msg = f"--alt-amsl {alt_amsl:.1f}: at or under the ground there ({ground:.1f} m AMSL)"
        raise OptionError(msg)
    state = pose_state(
        args.lat,
        args.lon,
        alt_amsl,
        alt_agl_m=alt_amsl - ground,
        roll_rad=math.radians(args.roll),
        pitch_rad=math.radians(args.pitch),
        yaw_rad=math.radians(args.yaw),
    )
    img = renderer.render(state, noise_index=args.frame_index)
    if (share := renderer.nodata_fraction()) > 0.0:
        print(
            f"air-sitl: warning: map {map_source.name}: {share * 100:.1f} % of the frame shows "
            "nodata or ground off the map",
            file=sys.stderr,
        )
    if out.suffix.lower() == ".png":
        _ok, buf = cv2.imencode(".png", img)
        data = bytes(buf)
    else:
        data = renderer.encode(img)
    write_bytes_atomic(out, data)
    centre = renderer.map_xy_px(state)
    where = "no ground" if centre is None else f"map px {centre[0]:.1f}, {centre[1]:.1f}"
    print(f"{out}: {camera.width_px}x{camera.height_px}, centre at {where}", file=sys.stdout)
    return 0
