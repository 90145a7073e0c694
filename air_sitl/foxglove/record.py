"""``export ARCHIVE --mcap FILE``: an archive's flight as the live view's Foxglove topics.

Per frame: ``camera/image`` (the archive's JPEG bytes), ``camera/calibration``, ``truth/fix``,
``truth/pose``, ``/tf`` and ``camera/footprint``; ``gnss/fix`` at each new receiver fix and
``nav/fix``, ``nav/pose`` from ``frames.csv`` (our archives); ``estimates/<name>/fix`` and
``/pose`` from ``estimates/*.csv``; ``errors`` of the filter and the estimates against the truth
frame nearest in time; ``mission`` (GeoJSON of the archive's plan) at the first frame; ``log``:
the flight mode and mission item changes. Written with the SDK's MCAP writer.
"""

from __future__ import annotations

import bisect
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import foxglove

from air_sitl.bus.keys import DEFAULT_VEHICLE
from air_sitl.camera.model import CameraModel
from air_sitl.dataset.air_schema import ESTIMATES_DIR
from air_sitl.dataset.estimates import parse_estimates
from air_sitl.dataset.export import check_out
from air_sitl.dataset.manifest import manifest_home
from air_sitl.dataset.reader import Archive
from air_sitl.errors import DatasetError, PlanError
from air_sitl.foxglove import topics as tp
from air_sitl.frames import ned2geodetic, q_frd_ned_to_flu_enu
from air_sitl.mission.plan_json import plan_from_text
from air_sitl.state import GeoPoint, Quat, Vec3


def archive_camera(archive: Archive) -> CameraModel:
    """The archive's camera (camera.yaml; AIR's 640x480, 57 deg without one)."""
    cam = archive.camera()
    if cam is None:
        return CameraModel()
    try:
        rpy = tuple(float(a) for a in cam.get("mount_rpy_deg", (0.0, 0.0, 0.0)))
        return CameraModel(
            width_px=int(cam["image_width"]),
            height_px=int(cam["image_height"]),
            hfov_deg=float(cam["hfov_deg"]),
            mount_rpy_deg=(rpy[0], rpy[1], rpy[2]),
        )
    except (KeyError, TypeError, ValueError, IndexError) as err:
        msg = f"{archive.path}/camera.yaml: missing or bad field ({err})"
        raise DatasetError(msg) from None


def _xyzw_to_wxyz(q: Quat) -> Quat:
    return (q[3], q[0], q[1], q[2])


def _float(row: dict[str, str], key: str) -> float:
    try:
        return float(row.get(key, "") or "nan")
    except ValueError:
        return math.nan


def _enu_to_geo(enu: Vec3, home: GeoPoint) -> GeoPoint:
    lat, lon, alt = ned2geodetic(
        enu[1], enu[0], -enu[2], home.lat_deg, home.lon_deg, home.alt_amsl_m
    )
    return GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)


class _ArchiveTopics:
    """Logs an archive's topics on :class:`tp.Channels`."""

    def __init__(self, archive: Archive, channels: tp.Channels) -> None:
        self.archive = archive
        self.ch = channels
        self.camera = archive_camera(archive)
        self.home = manifest_home(archive.manifest)
        self.times = [archive.timestamp_ns(k) for k in range(len(archive.rows))]

    def frame(self, k: int) -> None:
        a, ch, cam = self.archive, self.ch, self.camera
        t, row = self.times[k], a.rows[k]
        extra = a.extra_rows[k] if a.extra_rows is not None and k < len(a.extra_rows) else None
        q = _xyzw_to_wxyz(row.orientation_xyzw)
        ch.log(tp.IMAGE, t, tp.image(t, a.jpeg(k)))
        ch.log(tp.CALIBRATION, t, tp.calibration(t, cam))
        alt = _float(extra, "alt_amsl_m") if extra is not None else row.rel_alt_m
        truth = GeoPoint(lat_deg=row.lat_deg, lon_deg=row.lon_deg, alt_amsl_m=alt)
        ch.log(f"{tp.TRUTH}/fix", t, tp.location_fix(t, truth, tp.colour_of(tp.TRUTH)))
        ch.log(f"{tp.TRUTH}/pose", t, tp.pose(t, row.pose_enu_m, q))
        ch.log(tp.TF_TOPIC, t, tp.transforms(t, row.pose_enu_m, q, cam))
        if self.home is not None:
            height = _float(extra, "alt_rel_m") if extra is not None else row.rel_alt_m
            corners = tp.footprint_lonlat(cam, row.pose_enu_m, q, height, self.home)
            if corners is not None:
                ch.log(tp.FOOTPRINT, t, tp.footprint(corners))
        if extra is not None:
            self._extra(k, t, extra, row.pose_enu_m)

    def _extra(self, k: int, t: int, extra: dict[str, str], truth_enu: Vec3) -> None:
        ch = self.ch
        prev = self.archive.extra_rows[k - 1] if k > 0 and self.archive.extra_rows else None
        fix_type = _float(extra, "gps_fix_type")
        if fix_type >= 2 and (prev is None or prev.get("gps_time_ns") != extra["gps_time_ns"]):
            gps_t = int(extra["gps_time_ns"])
            geo = GeoPoint(
                lat_deg=_float(extra, "gps_lat_deg"),
                lon_deg=_float(extra, "gps_lon_deg"),
                alt_amsl_m=_float(extra, "gps_alt_amsl_m"),
            )
            cov = tp.diagonal_cov(_float(extra, "gps_eph_m"), _float(extra, "gps_epv_m"))
            fix = tp.location_fix(
                gps_t, geo, tp.colour_of(tp.GNSS), cov_enu_m2=cov, approximated=True
            )
            ch.log(f"{tp.GNSS}/fix", gps_t, fix)
        nav_lat = _float(extra, "nav_lat_deg")
        if math.isfinite(nav_lat):
            geo = GeoPoint(
                lat_deg=nav_lat,
                lon_deg=_float(extra, "nav_lon_deg"),
                alt_amsl_m=_float(extra, "nav_alt_amsl_m"),
            )
            std_h = _float(extra, "nav_std_h_m")
            nav_cov = tp.diagonal_cov(std_h, std_h) if math.isfinite(std_h) else None
            ch.log(
                f"{tp.NAV}/fix",
                t,
                tp.location_fix(
                    t, geo, tp.colour_of(tp.NAV), cov_enu_m2=nav_cov, approximated=True
                ),
            )
            enu = (
                _float(extra, "nav_east_m"),
                _float(extra, "nav_north_m"),
                _float(extra, "nav_up_m"),
            )
            ch.log(f"{tp.NAV}/pose", t, tp.pose(t, enu, None))
            ch.log(tp.ERRORS, t, tp.errors(t, tp.NAV, truth_enu, enu))
        for key, what in (("mode", "mode"), ("mission_seq", "mission item")):
            if prev is None or prev.get(key) != extra.get(key):
                ch.log(tp.LOG, t, tp.log(t, f"{what} {extra.get(key, '')}", name="vehicle"))

    def mission(self) -> None:
        plans = sorted(n for n in self.archive.names() if n.endswith(".plan") and "/" not in n)
        if not plans or not self.times:
            return
        where = f"{self.archive.path}/{plans[0]}"
        try:
            mission = plan_from_text(self.archive.read_bytes(plans[0]).decode("utf-8"), where)
        except (PlanError, UnicodeDecodeError) as err:
            sys.stderr.write(
                f"warning: {where}: no mission topic, the plan is unreadable ({err})\n"
            )
            return
        self.ch.log(tp.MISSION, self.times[0], tp.mission_geojson(mission))

    def estimates(self) -> None:
        a = self.archive
        names = sorted(
            n
            for n in a.names()
            if n.startswith(f"{ESTIMATES_DIR}/") and n.endswith(".csv") and n.count("/") == 1
        )
        for index, name in enumerate(names):
            est = name[len(ESTIMATES_DIR) + 1 : -len(".csv")]
            source = tp.estimate_source(est)
            colour = tp.colour_of(source, index)
            try:
                text = a.read_bytes(name).decode("utf-8")
            except UnicodeDecodeError as err:
                msg = f"{a.path}/{name}: not UTF-8 text ({err})"
                raise DatasetError(msg) from None
            for p in parse_estimates(text, f"{a.path}/{name}", self.home):
                if p.sim_time_ns is not None:
                    t = p.sim_time_ns
                elif p.frame is not None and 0 <= p.frame < len(self.times):
                    t = self.times[p.frame]
                else:
                    continue
                q = None
                if p.q_body_to_ned_wxyz is not None:
                    q = q_frd_ned_to_flu_enu(p.q_body_to_ned_wxyz)
                self.ch.log(f"{source}/pose", t, tp.pose(t, p.enu_m, q))
                if self.home is not None:
                    geo = _enu_to_geo(p.enu_m, self.home)
                    self.ch.log(f"{source}/fix", t, tp.location_fix(t, geo, colour))
                k = self._nearest(t)
                if k is not None:
                    truth = a.rows[k].pose_enu_m
                    self.ch.log(tp.ERRORS, t, tp.errors(t, source, truth, p.enu_m))

    def _nearest(self, t: int) -> int | None:
        if not self.times:
            return None
        i = bisect.bisect_left(self.times, t)
        cands = [j for j in (i - 1, i) if 0 <= j < len(self.times)]
        return min(cands, key=lambda j: abs(self.times[j] - t))


def export_mcap(
    archive: Archive,
    out: Path,
    *,
    vehicle: str = DEFAULT_VEHICLE,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, int]:
    """Write the archive's topics to the MCAP file ``out``; returns messages per topic.
    ``progress(frames written, frames)`` hears every 50th frame and the last."""
    check_out(out)
    context = foxglove.Context()
    try:
        writer: Any = foxglove.open_mcap(out, context=context)
    except Exception as err:  # the SDK raises its own FoxgloveError
        msg = f"{out}: cannot create the MCAP file: {err}"
        raise DatasetError(msg) from None
    channels = tp.Channels(context, vehicle)
    try:
        topics = _ArchiveTopics(archive, channels)
        topics.mission()
        total = len(archive.rows)
        for k in range(total):
            topics.frame(k)
            if progress is not None and ((k + 1) % 50 == 0 or k + 1 == total):
                progress(k + 1, total)
        topics.estimates()
    finally:
        channels.close()
        writer.close()
    return dict(channels.counts)
