"""Write a SpotOrientation as a SPOT level-1A DIMAP METADATA.DIM that `dimap.read_dimap` reads back.

Same conventions as the reader (`dimap.py`): DIMAP lines and detectors count from 1 on pixel centres,
times are ISO UTC strings. The frame corners come from the rigorous model (`spot.SpotModel`).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from typing import SupportsFloat

import numpy as np

from ..atomic import write_text
from ..errors import InputError
from .dimap import dim_path
from .spot import SpotModel
from .spot_orientation import SpotOrientation


def _num(value: SupportsFloat) -> str:
    """Shortest text that reads back to the same float (integral values without '.0')."""
    value = float(value)
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)


def _iso(epoch: np.datetime64, seconds: SupportsFloat) -> str:
    """ISO UTC text of epoch + seconds: microseconds as in SPOT products, nanoseconds when needed."""
    ns = int(round(float(seconds) * 1e9))
    text = str(epoch + np.timedelta64(ns, "ns"))
    return text[:-3] if text.endswith("000") else text


def _sub(parent: ET.Element, tag: str, text: object = None, **attrib: str) -> ET.Element:
    e = ET.SubElement(parent, tag, attrib)
    if text is not None:
        e.text = str(text)
    return e


def _angles(parent: ET.Element, tag: str, epoch: np.datetime64, t: np.ndarray, ypr: np.ndarray) -> None:
    for ti, (y, p, r) in zip(t, ypr):
        e = _sub(parent, tag)
        _sub(e, "TIME", _iso(epoch, ti))
        for k, v in zip(("YAW", "PITCH", "ROLL"), (y, p, r)):
            _sub(e, k, _num(v))
        _sub(e, "OUT_OF_RANGE", "N")


def _look_table(o: SpotOrientation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detector ids and angles to write: SPOT 1-4 tables that are linear keep only the end detectors."""
    ids = np.arange(1, o.ncols + 1)
    if o.mission <= 4:
        ends = np.array([0, o.ncols - 1])
        if all(np.array_equal(np.interp(ids, ids[ends], psi[ends]), psi) for psi in (o.psi_x, o.psi_y)):
            return ids[ends], o.psi_x[ends], o.psi_y[ends]
    return ids, o.psi_x, o.psi_y


def _frame(root: ET.Element, model: SpotModel, o: SpotOrientation) -> None:
    """Dataset_Frame, CRS, raster CS and Geoposition tie points: the corners at height 0."""
    corners = [(1, 1), (1, o.ncols), (o.nrows, o.ncols), (o.nrows, 1)]
    centre = (int(round(o.centre_row + 0.5)), o.ncols // 2 + 1)
    rows = np.array([c[0] for c in corners + [centre]], float) - 0.5
    cols = np.array([c[1] for c in corners + [centre]], float) - 0.5
    lon, lat = (np.asarray(v) for v in model.image_to_ground(cols, rows, np.zeros(rows.size)))  # arrays: cols, rows are
    frame = _sub(root, "Dataset_Frame")
    for i, (row, col) in enumerate(corners + [centre]):
        v = _sub(frame, "Vertex" if i < 4 else "Scene_Center")
        for tag, value in (
            ("FRAME_LON", _num(lon[i])),
            ("FRAME_LAT", _num(lat[i])),
            ("FRAME_ROW", row),
            ("FRAME_COL", col),
        ):
            _sub(v, tag, value)
    # SCENE_ORIENTATION: angle (degrees, clockwise) from east to the direction of the lines
    east = 0.5 * (lon[1] - lon[0] + lon[2] - lon[3]) * np.cos(np.radians(lat[4]))
    north = 0.5 * (lat[1] - lat[0] + lat[2] - lat[3])
    _sub(frame, "SCENE_ORIENTATION", _num(np.degrees(np.arctan2(-north, east))))
    crs = _sub(root, "Coordinate_Reference_System")
    _sub(crs, "GEO_TABLES", "EPSG", version="5.2")
    hcs = _sub(crs, "Horizontal_CS")
    _sub(hcs, "HORIZONTAL_CS_CODE", "epsg:4326")
    _sub(hcs, "HORIZONTAL_CS_TYPE", "GEOGRAPHIC")
    _sub(hcs, "HORIZONTAL_CS_NAME", "WGS 84")
    rcs = _sub(root, "Raster_CS")
    _sub(rcs, "RASTER_CS_TYPE", "POINT")
    _sub(rcs, "PIXEL_ORIGIN", "1")
    ties = _sub(_sub(root, "Geoposition"), "Geoposition_Points")
    for i, (row, col) in enumerate(corners):
        tp = _sub(ties, "Tie_Point")
        for tag, number in (
            ("TIE_POINT_CRS_X", lon[i]),
            ("TIE_POINT_CRS_Y", lat[i]),
            ("TIE_POINT_CRS_Z", 0.0),
            ("TIE_POINT_DATA_X", col),
            ("TIE_POINT_DATA_Y", row),
        ):
            _sub(tp, tag, _num(number))


def _source(root: ET.Element, o: SpotOrientation, sun: Sequence[float] | None) -> None:
    centre = o.epoch + np.timedelta64(int(round(o.centre_time * 1e9)), "ns")
    day, clock = str(centre.astype("datetime64[s]")).split("T")
    sources = _sub(_sub(root, "Dataset_Sources"), "Source_Information")
    _sub(sources, "SOURCE_TYPE", "SCENE")
    _sub(sources, "SOURCE_DESCRIPTION", f"SCENE {o.instrument}{o.instrument_index} {o.sensor_code}".strip())
    scene = _sub(sources, "Scene_Source")
    for tag, value in (
        ("IMAGING_DATE", day),
        ("IMAGING_TIME", clock),
        ("MISSION", "SPOT"),
        ("MISSION_INDEX", o.mission),
        ("INSTRUMENT", o.instrument),
        ("INSTRUMENT_INDEX", o.instrument_index),
        ("SENSOR_CODE", o.sensor_code),
        ("SCENE_PROCESSING_LEVEL", "1A"),
    ):
        _sub(scene, tag, value)
    if sun is not None:
        _sub(scene, "SUN_AZIMUTH", _num(sun[0]))
        _sub(scene, "SUN_ELEVATION", _num(sun[1]))


def _raster(root: ET.Element, o: SpotOrientation, nbits: int, nbands: int, data_file: str) -> None:
    dims = _sub(root, "Raster_Dimensions")
    for tag, value in (("NCOLS", o.ncols), ("NROWS", o.nrows), ("NBANDS", nbands)):
        _sub(dims, tag, value)
    enc = _sub(root, "Raster_Encoding")
    for tag, text in (("NBITS", nbits), ("BYTEORDER", "I"), ("COMPRESSION_NAME", "NONE"), ("DATA_TYPE", "UNSIGNED")):
        _sub(enc, tag, text)
    access = _sub(root, "Data_Access")
    _sub(access, "DATA_FILE_ORGANISATION", "BAND_COMPOSITE")
    _sub(access, "DATA_FILE_FORMAT", "GEOTIFF", version="1.0")
    _sub(_sub(access, "Data_File"), "DATA_FILE_PATH", href=data_file)
    proc = _sub(root, "Data_Processing")
    _sub(proc, "PROCESSING_LEVEL", "1A")
    _sub(proc, "GEOMETRIC_PROCESSING", "RAW")
    interp = _sub(root, "Image_Interpretation")
    for band in range(1, nbands + 1):
        info = _sub(interp, "Spectral_Band_Info")
        _sub(info, "BAND_INDEX", band)
        _sub(info, "BAND_DESCRIPTION", "PAN" if nbands == 1 else f"XS{band}")


def _data_strip(root: ET.Element, o: SpotOrientation) -> None:
    strip = _sub(root, "Data_Strip")
    eph = _sub(strip, "Ephemeris")
    points = _sub(eph, "Points")
    for t, pos, vel in zip(o.eph_t, o.eph_pos, o.eph_vel):
        p = _sub(points, "Point")
        for name, xyz in (("Location", pos), ("Velocity", vel)):
            e = _sub(p, name)
            for axis, v in zip("XYZ", xyz):
                _sub(e, axis, _num(v))
        _sub(p, "TIME", _iso(o.epoch, t))
    att = _sub(strip, "Satellite_Attitudes")
    if o.mission == 5:
        corrected = _sub(att, "Corrected_Attitudes")
        _sub(corrected, "STAR_TRACKER_USED", "Y")
        _angles(_sub(corrected, "Corrected_Attitude"), "Angles", o.epoch, o.att_t, o.att_ypr)
    else:
        aocs = _sub(_sub(att, "Raw_Attitudes"), "Aocs_Attitude")
        _angles(_sub(aocs, "Angles_List"), "Angles", o.epoch, o.att_t, o.att_ypr)
        if o.speed_t is not None and o.speed_ypr is not None:  # validate() checked the rates of these times
            _angles(_sub(aocs, "Angular_Speeds_List"), "Angular_Speeds", o.epoch, o.speed_t, o.speed_ypr)
    sensor = _sub(strip, "Sensor_Configuration")
    stamp = _sub(sensor, "Time_Stamp")
    _sub(stamp, "LINE_PERIOD", _num(o.line_period))
    _sub(stamp, "SCENE_CENTER_TIME", _iso(o.epoch, o.centre_time))
    _sub(stamp, "SCENE_CENTER_LINE", _num(o.centre_row + 0.5))
    _sub(stamp, "SCENE_CENTER_COL", o.ncols // 2 + 1)
    table = _sub(_sub(sensor, "Instrument_Look_Angles_List"), "Instrument_Look_Angles")
    _sub(table, "BAND_INDEX", 1)
    angles = _sub(table, "Look_Angles_List")
    for i, px, py in zip(*_look_table(o)):
        e = _sub(angles, "Look_Angles")
        _sub(e, "DETECTOR_ID", int(i))
        _sub(e, "PSI_X", _num(px))
        _sub(e, "PSI_Y", _num(py))
    if o.mirror_step is not None:
        _sub(_sub(sensor, "Mirror_Position"), "STEP_COUNT", int(o.mirror_step))


def write_dimap(
    path: str | os.PathLike[str],
    orientation: SpotOrientation,
    sun: Sequence[float] | None = None,
    nbits: int = 8,
    nbands: int = 1,
    data_file: str = "IMAGERY.TIF",
) -> None:
    """Write `orientation` as a SPOT level-1A METADATA.DIM (atomically) that `read_dimap` reads
    back unchanged and GDAL's DIMAP driver opens with its `data_file`.

    Dataset_Frame corners are computed with the rigorous model at height 0. `sun`: optional
    (azimuth, elevation) in degrees. Correction polynomials have no place in DIMAP: an orientation
    that carries any is refused (save adjusted models with sensors.save)."""
    o = orientation
    c = o.corrections
    if any(np.any(np.asarray(a) != 0) for a in (c.position, c.attitude, c.look)):
        raise InputError(
            "DIMAP cannot hold correction polynomials; save the adjusted model with "
            "sensors.save (the project's model file) instead"
        )
    model = SpotModel(o)  # validates the orientation
    root = ET.Element("Dimap_Document", {"name": "METADATA.DIM"})
    meta = _sub(root, "Metadata_Id")
    _sub(meta, "METADATA_FORMAT", "DIMAP", version="1.1")
    _sub(meta, "METADATA_PROFILE", "SPOTSCENE_1A")
    _sub(_sub(root, "Dataset_Id"), "DATASET_NAME", o.name or "SCENE")
    _frame(root, model, o)
    _sub(_sub(_sub(root, "Production"), "Production_Facility"), "SOFTWARE_NAME", "PUSHBROOM")
    _source(root, o, sun)
    _raster(root, o, nbits, nbands, data_file)
    _data_strip(root, o)
    ET.indent(root)
    text = '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    write_text(dim_path(path), text)
