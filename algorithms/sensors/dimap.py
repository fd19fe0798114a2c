"""Read SPOT 1-5 level-1A DIMAP metadata (METADATA.DIM) as a SpotOrientation (written by `dimap_writer`).

Pixel convention, converted here and nowhere else: DIMAP counts lines and detectors from 1 and
puts integer coordinates on pixel centres (PIXEL_ORIGIN 1, RASTER_CS_TYPE POINT). GDAL's (col, row)
has (0, 0) at the top-left corner of the first pixel, so
    row = LINE - 0.5,  col = DETECTOR - 0.5   (DIMAP line/detector 1 -> GDAL centre 0.5).
Times: ISO UTC strings -> seconds (float) since `epoch`, the scene-centre time floored to the
second (numpy datetime64, ns precision).

What is read: ephemeris (Points), attitudes (SPOT 5: Corrected_Attitudes; SPOT 1-4: Raw_Attitudes
Angles_List and Angular_Speeds_List), look angles (SPOT 5: one per detector; SPOT 1-4: first and
last detector, interpolated linearly in psi_x and psi_y along the array as the handbook prescribes;
the angles already include the mirror pointing, STEP_COUNT is kept for information), line period and
scene-centre time/line. Samples flagged OUT_OF_RANGE = Y are dropped. Multispectral products: the
look angles of the first Instrument_Look_Angles (band 1) are used.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from typing import NoReturn

import numpy as np

from ..errors import MetadataError
from .spot_orientation import MAX_SIZE, Corrections, SpotOrientation


class _Doc:
    """A parsed METADATA.DIM whose accessors raise MetadataError naming the file and element."""

    def __init__(self, path: str) -> None:
        self.path = path
        try:
            self.root = ET.parse(path).getroot()
        except ET.ParseError as exc:
            raise MetadataError(
                f"{path}: not well-formed XML ({exc}); the file is truncated or "
                "damaged, copy it again from the delivered product"
            ) from exc
        except OSError as exc:
            raise MetadataError(f"{path}: cannot read ({exc})") from exc
        if self.root.tag != "Dimap_Document":
            raise MetadataError(
                f"{path}: root element is <{self.root.tag}>, not <Dimap_Document>; not a SPOT DIMAP METADATA.DIM"
            )

    def fail(self, what: str) -> NoReturn:
        raise MetadataError(f"{self.path}: {what}; is this a complete SPOT level-1A METADATA.DIM?")

    def node(self, xpath: str, base: ET.Element | None = None) -> ET.Element:
        found = (self.root if base is None else base).find(xpath)
        if found is None:
            self.fail(f"missing <{xpath}>")
        return found

    def nodes(self, xpath: str, base: ET.Element | None = None) -> list[ET.Element]:
        found = (self.root if base is None else base).findall(xpath)
        if not found:
            self.fail(f"no <{xpath}> element")
        return found

    def text(self, xpath: str, base: ET.Element | None = None) -> str:
        value = (self.node(xpath, base).text or "").strip()
        if not value:
            self.fail(f"<{xpath}> is empty")
        return value

    def number(self, xpath: str, base: ET.Element | None = None) -> float:
        text = self.text(xpath, base)
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not np.isfinite(value):
            self.fail(f"<{xpath}> = {text!r} is not a finite number")
        return value

    def integer(self, xpath: str, base: ET.Element | None = None) -> int:
        value = self.number(xpath, base)
        if value != int(value):
            self.fail(f"<{xpath}> = {value} is not an integer")
        return int(value)

    def time(self, xpath: str, base: ET.Element | None = None) -> np.datetime64:
        text = self.text(xpath, base).rstrip("Z")
        try:
            value = np.datetime64(text, "ns")
        except (ValueError, OverflowError):
            value = np.datetime64("NaT")
        if np.isnat(value) or "T" not in text:
            self.fail(f"<{xpath}> = {text!r} is not an ISO UTC date-time")
        return value

    def valid(self, items: Iterable[ET.Element]) -> list[ET.Element]:
        """Items whose OUT_OF_RANGE flag is not Y."""
        return [e for e in items if (e.findtext("OUT_OF_RANGE") or "N").strip() != "Y"]


def _seconds(times: Sequence[np.datetime64], epoch: np.datetime64) -> np.ndarray:
    return (np.asarray(times, dtype="datetime64[ns]") - epoch) / np.timedelta64(1, "ns") * 1e-9


def _xyz(doc: _Doc, base: ET.Element, name: str) -> list[float]:
    return [doc.number(f"{name}/{axis}", base) for axis in "XYZ"]


def _angle_series(doc: _Doc, items: list[ET.Element], epoch: np.datetime64) -> tuple[np.ndarray, np.ndarray]:
    """(t, (n, 3) yaw/pitch/roll) of <Angles> or <Angular_Speeds> elements."""
    items = doc.valid(items)
    t = _seconds([doc.time("TIME", e) for e in items], epoch)
    ypr = np.array([[doc.number(k, e) for k in ("YAW", "PITCH", "ROLL")] for e in items]).reshape(-1, 3)
    return t, ypr


def _look_angles(doc: _Doc, mission: int, ncols: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-detector (psi_x, psi_y); SPOT 1-4 tables of the end detectors interpolated linearly."""
    table = doc.node("Data_Strip/Sensor_Configuration/Instrument_Look_Angles_List/Instrument_Look_Angles")
    rows = doc.nodes("Look_Angles_List/Look_Angles", table)
    ids = np.array([doc.integer("DETECTOR_ID", e) for e in rows])
    psi = np.array([[doc.number("PSI_X", e), doc.number("PSI_Y", e)] for e in rows])
    order = np.argsort(ids)
    ids, psi = ids[order], psi[order]
    if np.any(np.diff(ids) == 0):
        doc.fail("duplicate DETECTOR_ID in Look_Angles_List")
    if ids.size == ncols and ids[0] == 1 and ids[-1] == ncols:
        return psi[:, 0], psi[:, 1]
    if mission <= 4 and ids.size >= 2 and ids[0] == 1 and ids[-1] == ncols:
        detectors = np.arange(1, ncols + 1)
        return np.interp(detectors, ids, psi[:, 0]), np.interp(detectors, ids, psi[:, 1])
    doc.fail(
        f"Look_Angles_List gives {ids.size} detectors (ids {ids[0]}..{ids[-1]}) for NCOLS = {ncols}; "
        + ("SPOT 5 needs one per detector" if mission == 5 else "SPOT 1-4 need at least the first and last")
    )


def dim_path(path: str | os.PathLike[str]) -> str:
    """The METADATA.DIM file of `path` (the file itself, or the one inside the folder `path`)."""
    path = os.fspath(path)
    return os.path.join(path, "METADATA.DIM") if os.path.isdir(path) else path


def read_dimap(path: str | os.PathLike[str], image: str | os.PathLike[str] | None = None) -> SpotOrientation:
    """SpotOrientation of a SPOT 1-5 level-1A METADATA.DIM (or its product folder).

    `image`, when given, is the raster the metadata describes: its size must equal NCOLS x NROWS
    (given as the metadata or its folder: the product's DATA_FILE_PATH is checked when present)."""
    path = dim_path(path)
    doc = _Doc(path)
    if doc.root.find("Metadata_Identification") is not None:  # DIMAP v2: Pleiades, SPOT 6/7
        raise MetadataError(
            f"{path}: a DIMAP v2 document (Pleiades, SPOT 6/7), not a SPOT 1-5 METADATA.DIM; "
            "its geometry is an RPC: open the image (GDAL reads its RPC) or its RPC file"
        )
    src = doc.node("Dataset_Sources/Source_Information/Scene_Source")
    if doc.text("MISSION", src).upper() != "SPOT":
        doc.fail(f"MISSION is {doc.text('MISSION', src)!r}, not SPOT")
    mission = doc.integer("MISSION_INDEX", src)
    if mission not in (1, 2, 3, 4, 5):
        doc.fail(
            f"MISSION_INDEX {mission} is not SPOT 1 to 5 (SPOT 6/7 use DIMAP v2 with RPCs: open their RPC instead)"
        )
    ncols = doc.integer("Raster_Dimensions/NCOLS")
    nrows = doc.integer("Raster_Dimensions/NROWS")
    if not (2 <= ncols <= MAX_SIZE and 1 <= nrows <= MAX_SIZE):
        doc.fail(f"NCOLS x NROWS = {ncols} x {nrows} is not the size of a SPOT scene")
    stamp = doc.node("Data_Strip/Sensor_Configuration/Time_Stamp")
    centre = doc.time("SCENE_CENTER_TIME", stamp)
    epoch = centre.astype("datetime64[s]").astype("datetime64[ns]")

    points = doc.nodes("Data_Strip/Ephemeris/Points/Point")
    eph_t = _seconds([doc.time("TIME", p) for p in points], epoch)
    eph_pos = np.array([_xyz(doc, p, "Location") for p in points])
    eph_vel = np.array([_xyz(doc, p, "Velocity") for p in points])

    attitudes = doc.node("Data_Strip/Satellite_Attitudes")
    speed_t: np.ndarray | None = None
    speed_ypr: np.ndarray | None = None
    if mission == 5:
        att_t, att_ypr = _angle_series(
            doc, doc.nodes("Corrected_Attitudes/Corrected_Attitude/Angles", attitudes), epoch
        )
    else:
        aocs = doc.node("Raw_Attitudes/Aocs_Attitude", attitudes)
        att_t, att_ypr = _angle_series(doc, doc.nodes("Angles_List/Angles", aocs), epoch)
        if aocs.find("Angular_Speeds_List") is not None:
            speed_t, speed_ypr = _angle_series(doc, doc.nodes("Angular_Speeds_List/Angular_Speeds", aocs), epoch)

    psi_x, psi_y = _look_angles(doc, mission, ncols)
    mirror = doc.root.find("Data_Strip/Sensor_Configuration/Mirror_Position/STEP_COUNT")
    orientation = SpotOrientation(
        mission=mission,
        instrument=doc.text("INSTRUMENT", src).upper(),
        instrument_index=doc.integer("INSTRUMENT_INDEX", src),
        ncols=ncols,
        nrows=nrows,
        epoch=epoch,
        eph_t=eph_t,
        eph_pos=eph_pos,
        eph_vel=eph_vel,
        att_t=att_t,
        att_ypr=att_ypr,
        psi_x=psi_x,
        psi_y=psi_y,
        line_period=doc.number("LINE_PERIOD", stamp),
        centre_time=float(_seconds([centre], epoch)[0]),
        centre_row=doc.number("SCENE_CENTER_LINE", stamp) - 0.5,
        speed_t=speed_t,
        speed_ypr=speed_ypr,
        sensor_code=(src.findtext("SENSOR_CODE") or "").strip(),
        mirror_step=None
        if mirror is None
        else doc.integer("Data_Strip/Sensor_Configuration/Mirror_Position/STEP_COUNT"),
        corrections=Corrections(),
        name=(doc.root.findtext("Dataset_Id/DATASET_NAME") or path).strip(),
    )
    try:
        orientation.validate()
    except MetadataError as exc:
        raise MetadataError(f"{path}: {exc}") from None
    if image is not None and os.path.abspath(dim_path(image)) == os.path.abspath(path):
        image = _own_raster(doc, path)
    if image is not None:
        check_image_size(orientation, image, path)
    return orientation


def _own_raster(doc: _Doc, path: str) -> str | None:
    """The product's own raster (Data_Access DATA_FILE_PATH beside the metadata), if it exists."""
    href = doc.root.find("Data_Access/Data_File/DATA_FILE_PATH")
    raster = os.path.join(os.path.dirname(path), href.get("href", "")) if href is not None else ""
    return raster if os.path.isfile(raster) else None


def product_raster(path: str | os.PathLike[str]) -> str:
    """Path of the raster of the SPOT DIMAP product whose METADATA.DIM (or folder) is `path`: its
    Data_Access DATA_FILE_PATH beside the metadata, IMAGERY.TIF where it names none (whether it exists
    or not). MetadataError where the metadata cannot be read."""
    path = dim_path(path)
    href = _Doc(path).root.find("Data_Access/Data_File/DATA_FILE_PATH")
    name = (href.get("href") if href is not None else "") or "IMAGERY.TIF"
    return os.path.join(os.path.dirname(path), name)


def check_image_size(orientation: SpotOrientation, image: str | os.PathLike[str], path: str = "") -> None:
    """Raise MetadataError unless the raster `image` has NCOLS x NROWS pixels."""
    from osgeo import gdal

    gdal.UseExceptions()
    try:
        ds = gdal.Open(os.fspath(image))
    except RuntimeError as exc:
        raise MetadataError(f"cannot open the image {image}: {exc}") from exc
    size = (ds.RasterXSize, ds.RasterYSize)
    if size != (orientation.ncols, orientation.nrows):
        raise MetadataError(
            f"{path or orientation.name}: NCOLS x NROWS = {orientation.ncols} x {orientation.nrows} but the image "
            f"{image} has {size[0]} x {size[1]} pixels; the metadata belong to another product (or the image "
            "was cropped): use the METADATA.DIM delivered with this image"
        )
