"""Command-line options for maps and the camera, shared by fly, serve, dataset and render,
and the renderer they choose (the map and surface themselves: ``maps.choose``)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from air_sitl.camera.defaults import DEFAULT_JPEG_QUALITY, DEFAULT_NOISE_SIGMA, EFFECT_NAMES
from air_sitl.errors import CameraError
from air_sitl.options import MapChoice

if TYPE_CHECKING:  # the renderer and the maps load when a command runs, not for its --help
    from air_sitl.camera.model import CameraModel
    from air_sitl.camera.render import Renderer
    from air_sitl.maps.base import MapSource


def add_map_arguments(parser: argparse.ArgumentParser) -> None:
    """``--map``, ``--map-seed``, ``--map-date``."""
    group = parser.add_argument_group("map")
    group.add_argument(
        "--map",
        default=None,
        metavar="MAP",
        help="urban, forest, farmland (procedural) or a GeoTIFF path; several GeoTIFFs of one "
        "area as dates: a.tif,b.tif, or a folder of dated GeoTIFFs (map fetch's) in date order. "
        "Default: urban for plans named U*, forest for F*, farmland for A*, else urban",
    )
    group.add_argument(
        "--map-seed", type=int, default=0, metavar="N", help="seed of a procedural map (default 0)"
    )
    group.add_argument(
        "--map-date",
        default=None,
        metavar="D",
        help="date of the map: 0, 1, 2 (urban, forest: 2009-06-20 summer, 2012-10-08 autumn, "
        "2016-04-22 spring; farmland, in the growing season as NAIP: 2009-06-20, 2012-07-24, "
        "2016-08-13) or a GeoTIFF date file's index, acquisition date (YYYY-MM-DD "
        "or a year) or path (default 0)",
    )
    group.add_argument(
        "--dem",
        default=None,
        metavar="FILE",
        help="relief: a GeoTIFF elevation model (heights AMSL, any CRS) or 'builtin' (the "
        "procedural map's own terrain, roofs and canopy); default: flat ground at home",
    )


def add_camera_arguments(parser: argparse.ArgumentParser) -> None:
    """Camera size, field of view, mounting, JPEG quality and noise."""
    group = parser.add_argument_group("camera")
    group.add_argument("--camera-width", type=int, default=640, metavar="PX")
    group.add_argument("--camera-height", type=int, default=480, metavar="PX")
    group.add_argument(
        "--camera-hfov-deg", type=float, default=57.0, metavar="DEG", help="horizontal FOV"
    )
    group.add_argument("--jpeg-quality", type=int, default=DEFAULT_JPEG_QUALITY, metavar="Q")
    group.add_argument(
        "--noise-sigma",
        type=float,
        default=DEFAULT_NOISE_SIGMA,
        metavar="DN",
        help=f"Gaussian noise, grey levels of 255 (default {DEFAULT_NOISE_SIGMA}, 0 = off)",
    )
    group.add_argument(
        "--camera-mount-rpy-deg",
        default="0,0,0",
        metavar="R,P,Y",
        help="camera rotation from the default nadir mounting (nose at the image top), degrees",
    )
    group.add_argument(
        "--camera-profile",
        default=None,
        metavar="FILE.yaml",
        help="camera effects and their physical parameters (keys of CameraEffects: enabled, "
        "exposure_time_s, line_delay_s, vignette_power, distortion_coefficients ...)",
    )
    group.add_argument(
        "--camera-effects",
        default=None,
        metavar="LIST",
        help=f"camera effects to switch on: {','.join(EFFECT_NAMES)} (default: none, the "
        "perfect pinhole); their parameters as in --camera-profile's defaults",
    )


def map_choice_from_args(args: argparse.Namespace) -> MapChoice:
    """``--map``, ``--map-seed``, ``--map-date`` as a MapChoice."""
    return MapChoice(
        spec=args.map, seed=args.map_seed, date=args.map_date, dem=getattr(args, "dem", None)
    )


def open_chosen_renderer(
    choice: MapChoice, map_source: MapSource, camera: CameraModel, seed: int
) -> Renderer:
    """The Renderer of ``map_source`` for ``camera``, over the surface ``choice.dem`` names."""
    from air_sitl.camera.render import Renderer
    from air_sitl.maps.choose import open_chosen_surface

    return Renderer(map_source, camera, seed=seed, surface=open_chosen_surface(choice, map_source))


def camera_from_args(args: argparse.Namespace) -> CameraModel:
    """The CameraModel the options describe (CameraError on bad values)."""
    from air_sitl.camera.effects import effects_from_options
    from air_sitl.camera.model import CameraModel

    text = str(args.camera_mount_rpy_deg)
    try:
        parts = tuple(float(p) for p in text.split(","))
    except ValueError:
        parts = ()
    if len(parts) != 3:
        msg = f"--camera-mount-rpy-deg {text!r}: expected three numbers R,P,Y in degrees"
        raise CameraError(msg)
    return CameraModel(
        width_px=args.camera_width,
        height_px=args.camera_height,
        hfov_deg=args.camera_hfov_deg,
        mount_rpy_deg=(parts[0], parts[1], parts[2]),
        noise_sigma=args.noise_sigma,
        jpeg_quality=args.jpeg_quality,
        effects=effects_from_options(
            getattr(args, "camera_profile", None), getattr(args, "camera_effects", None)
        ),
    )
