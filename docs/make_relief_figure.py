"""The README's relief picture: the same frames over flat ground and over the built-in surface.

Run from the repository: ``.venv/bin/python docs/make_relief_figure.py`` writes
``docs/relief.jpg``: urban and forest (map seed 0, date 0) at 200 m above the ground, nadir,
no noise, each as the flat map (no ``--dem``) beside ``--dem builtin`` (roofs and crowns
lean away from the nadir and hide what is behind them; every pixel shows the first surface
its ray meets). Frames are the camera's own (640 x 480, 57 degree HFOV), shown at 60 %.
A few seconds on one core.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.maps.procedural import ProceduralMap
from air_sitl.maps.procedural.surface import ProceduralSurface
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
# The forest at home; the town at a street block 2.6 km from it (as the contact sheet).
CENTRES = {
    "urban": GeoPoint(lat_deg=54.696871, lon_deg=25.242495, alt_amsl_m=120.0),
    "forest": HOME,
}
ALT_M = 200.0
SCALE = 0.6

Image = npt.NDArray[np.uint8]


def frames(kind: str) -> tuple[Image, Image]:
    """(flat, over the built-in surface) frames of one map at ALT_M over its centre."""
    centre = CENTRES[kind]
    proc = ProceduralMap(kind, centre, seed=0, date=0)
    camera = CameraModel(noise_sigma=0.0)
    state = pose_state(centre.lat_deg, centre.lon_deg, centre.alt_amsl_m + ALT_M, alt_agl_m=ALT_M)
    flat = Renderer(proc, camera).render(state)
    relief = Renderer(proc, camera, surface=ProceduralSurface(proc)).render(state)
    return flat, relief


def labelled(img: Image, text: str) -> Image:
    """The frame at SCALE with a label in its top-left corner."""
    small = cv2.resize(img, None, fx=SCALE, fy=SCALE, interpolation=cv2.INTER_AREA)
    for colour, width in (((0, 0, 0), 4), ((255, 255, 255), 2)):
        cv2.putText(small, text, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, colour, width,
                    cv2.LINE_AA)  # fmt: skip
    return np.asarray(small, dtype=np.uint8)


def figure() -> Image:
    """Rows urban, forest; columns flat, --dem builtin."""
    rows = []
    for kind in ("urban", "forest"):
        flat, relief = frames(kind)
        alt = f"{ALT_M:.0f} m"
        rows.append(np.hstack([labelled(flat, f"{kind} {alt}, flat"),
                               labelled(relief, f"{kind} {alt}, --dem builtin")]))  # fmt: skip
    return np.vstack(rows)


def main() -> None:
    """Write the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/relief.jpg"))
    args = parser.parse_args()
    cv2.imwrite(str(args.out), figure(), [cv2.IMWRITE_JPEG_QUALITY, 90])
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
