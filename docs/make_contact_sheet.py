"""Contact sheet of the procedural maps: forest, urban and farmland, three dates, 100 to 3000 m.

Run from the repository: ``.venv/bin/python docs/make_contact_sheet.py`` writes
``docs/procedural_contact_sheet.png`` (rows: map and date; columns: height above the
ground). Frames are the camera's own (640 x 480, 57 degree HFOV, nadir, no noise), rendered
with the built-in surface (``--dem builtin``): what ``air-sitl render --dem builtin`` shows.
``--frames DIR`` also keeps every frame as a PNG. About 3 minutes on one core.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.maps.procedural import ProceduralMap
from air_sitl.maps.procedural.surface import ProceduralSurface
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
# Where each map is shown: the forest at home; the town 2.6 km from it, at a street block
# whose 3000 m view takes in the farm fields at the edge of town (map seed 0).
CENTRES = {
    "forest": HOME,
    "urban": GeoPoint(lat_deg=54.696871, lon_deg=25.242495, alt_amsl_m=120.0),
    # The farmland scenarios' home (York, Nebraska): quarter sections, a pivot, a farmstead.
    "farmland": GeoPoint(lat_deg=40.8968, lon_deg=-97.6227, alt_amsl_m=509.0),
}
ALTITUDES_M = (100.0, 200.0, 300.0, 3000.0)
ROWS = tuple((kind, date) for kind in ("forest", "urban", "farmland") for date in (0, 1, 2))
CELL = (400, 300)  # width, height of one frame on the sheet
LABEL_W, HEAD_H = 150, 34


def render_frame(kind: str, date: int, alt_m: float, seed: int) -> np.ndarray:
    """One nadir camera frame (BGR) over the map's centre at ``alt_m`` above its ground."""
    centre = CENTRES[kind]
    proc = ProceduralMap(kind, centre, seed=seed, date=date)
    renderer = Renderer(proc, CameraModel(noise_sigma=0.0), surface=ProceduralSurface(proc))
    alt_amsl = centre.alt_amsl_m + alt_m
    state = pose_state(centre.lat_deg, centre.lon_deg, alt_amsl, alt_agl_m=alt_m)
    return renderer.render(state)


def _text(img: np.ndarray, text: str, org: tuple[int, int], scale: float = 0.6) -> None:
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (20, 20, 20), 1, cv2.LINE_AA)


def contact_sheet(seed: int, frames_dir: Path | None) -> np.ndarray:
    """The labelled grid of frames."""
    cw, ch = CELL
    sheet = np.full(
        (HEAD_H + len(ROWS) * (ch + 4), LABEL_W + len(ALTITUDES_M) * (cw + 4), 3),
        255,
        dtype=np.uint8,
    )
    for c, alt in enumerate(ALTITUDES_M):
        _text(sheet, f"{alt:.0f} m above ground", (LABEL_W + c * (cw + 4) + 110, 24))
    for r, (kind, date) in enumerate(ROWS):
        y = HEAD_H + r * (ch + 4)
        label = ProceduralMap(kind, CENTRES[kind], seed=seed, date=date).date
        _text(sheet, kind, (10, y + ch // 2 - 12), 0.8)
        _text(sheet, f"{label.label}", (10, y + ch // 2 + 14), 0.55)
        _text(sheet, f"({label.season})", (10, y + ch // 2 + 36), 0.55)
        for c, alt in enumerate(ALTITUDES_M):
            frame = render_frame(kind, date, alt, seed)
            if frames_dir is not None:
                cv2.imwrite(str(frames_dir / f"{kind}_d{date}_{alt:.0f}m.png"), frame)
            x = LABEL_W + c * (cw + 4)
            sheet[y : y + ch, x : x + cw] = cv2.resize(frame, CELL, interpolation=cv2.INTER_AREA)
    return sheet


def main() -> None:
    here = Path(__file__).resolve().parent
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=here / "procedural_contact_sheet.png")
    parser.add_argument("--seed", type=int, default=0, help="map seed (default 0)")
    parser.add_argument("--frames", type=Path, help="also write each frame here (PNG)")
    args = parser.parse_args()
    if args.frames is not None:
        args.frames.mkdir(parents=True, exist_ok=True)
    sheet = contact_sheet(args.seed, args.frames)
    # 256 colours (median cut, dithered): a photo-like sheet at a quarter of the bytes.
    rgb = Image.fromarray(np.ascontiguousarray(sheet[:, :, ::-1]))
    rgb.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.FLOYDSTEINBERG).save(
        args.out, optimize=True
    )
    print(f"wrote {args.out} ({sheet.shape[1]} x {sheet.shape[0]} px)")


if __name__ == "__main__":
    main()
