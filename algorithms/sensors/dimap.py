"""Read and write SPOT 1-5 level-1A DIMAP metadata (METADATA.DIM) as a SpotOrientation.

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
import os
import xml.etree.ElementTree as ET

import numpy as np

from ..atomic import write_text
from ..errors import InputError, MetadataError
from .spot_orientation import MAX_SIZE, Corrections, SpotOrientation


class _Doc:
    """A parsed METADATA.DIM whose accessors raise MetadataError naming the file and element."""

    def __init__(self, path):
        self.path = path
        try:
            self.root = ET.parse(path).getroot()
        except ET.ParseError as exc:
            raise MetadataError(f"{path}: not well-formed XML ({exc}); the file is truncated or "
                                "damaged, copy it again from the delivered product") from exc
        except OSError as exc:
            raise MetadataError(f"{path}: cannot read ({exc})") from exc
        if self.root.tag != "Dimap_Document":
            raise MetadataError(f"{path}: root element is <{self.root.tag}>, not <Dimap_Document>; "
                                "not a SPOT DIMAP METADATA.DIM")

    def fail(self, what):
        raise MetadataError(f"{self.path}: {what}; is this a complete SPOT level-1A METADATA.DIM?")

    def node(self, xpath, base=None):
        found = (self.root if base is None else base).find(xpath)
        if found is None:
            self.fail(f"missing <{xpath}>")
        return found

    def nodes(self, xpath, base=None):
        found = (self.root if base is None else base).findall(xpath)
        if not found:
            self.fail(f"no <{xpath}> element")
        return found

    def text(self, xpath, base=None):
        value = (self.node(xpath, base).text or "").strip()
        if not value:
            self.fail(f"<{xpath}> is empty")
        return value

    def number(self, xpath, base=None):
        text = self.text(xpath, base)
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not np.isfinite(value):
            self.fail(f"<{xpath}> = {text!r} is not a finite number")
        return value

    def integer(self, xpath, base=None):
        value = self.number(xpath, base)
        if value != int(value):
            self.fail(f"<{xpath}> = {value} is not an integer")
        return int(value)

    def time(self, xpath, base=None):
        text = self.text(xpath, base).rstrip("Z")
        try:
            value = np.datetime64(text, "ns")
        except (ValueError, OverflowError):
            value = np.datetime64("NaT")
        if np.isnat(value) or "T" not in text:
            self.fail(f"<{xpath}> = {text!r} is not an ISO UTC date-time")
        return value

    def valid(self, items):
        """Items whose OUT_OF_RANGE flag is not Y."""
        return [e for e in items if (e.findtext("OUT_OF_RANGE") or "N").strip() != "Y"]


def _seconds(times, epoch):
    return (np.asarray(times, dtype="datetime64[ns]") - epoch) / np.timedelta64(1, "ns") * 1e-9


def _xyz(doc, base, name):
    return [doc.number(f"{name}/{axis}", base) for axis in "XYZ"]


def _angle_series(doc, items, epoch):
    """(t, (n, 3) yaw/pitch/roll) of <Angles> or <Angular_Speeds> elements."""
    items = doc.valid(items)
    t = _seconds([doc.time("TIME", e) for e in items], epoch)
    ypr = np.array([[doc.number(k, e) for k in ("YAW", "PITCH", "ROLL")] for e in items]).reshape(-1, 3)
    return t, ypr


def _look_angles(doc, mission, ncols):
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
    doc.fail(f"Look_Angles_List gives {ids.size} detectors (ids {ids[0]}..{ids[-1]}) for NCOLS = {ncols}; "
             + ("SPOT 5 needs one per detector" if mission == 5 else "SPOT 1-4 need at least the first and last"))


def _dim_path(path):
    path = os.fspath(path)
    return os.path.join(path, "METADATA.DIM") if os.path.isdir(path) else path


def read_dimap(path, image=None):
    """SpotOrientation of a SPOT 1-5 level-1A METADATA.DIM (or its product folder).

    `image`, when given, is the raster the metadata describes: its size must equal NCOLS x NROWS
    (given as the metadata or its folder: the product's DATA_FILE_PATH is checked when present)."""
    path = _dim_path(path)
    doc = _Doc(path)
    if doc.root.find("Metadata_Identification") is not None:  # DIMAP v2: Pleiades, SPOT 6/7
        raise MetadataError(f"{path}: a DIMAP v2 document (Pleiades, SPOT 6/7), not a SPOT 1-5 METADATA.DIM; "
                            "its geometry is an RPC: open the image (GDAL reads its RPC) or its RPC file")
    src = doc.node("Dataset_Sources/Source_Information/Scene_Source")
    if doc.text("MISSION", src).upper() != "SPOT":
        doc.fail(f"MISSION is {doc.text('MISSION', src)!r}, not SPOT")
    mission = doc.integer("MISSION_INDEX", src)
    if mission not in (1, 2, 3, 4, 5):
        doc.fail(f"MISSION_INDEX {mission} is not SPOT 1 to 5 (SPOT 6/7 use DIMAP v2 with RPCs: "
                 "open their RPC instead)")
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
    speed_t = speed_ypr = None
    if mission == 5:
        att_t, att_ypr = _angle_series(doc, doc.nodes("Corrected_Attitudes/Corrected_Attitude/Angles", attitudes),
                                       epoch)
    else:
        aocs = doc.node("Raw_Attitudes/Aocs_Attitude", attitudes)
        att_t, att_ypr = _angle_series(doc, doc.nodes("Angles_List/Angles", aocs), epoch)
        if aocs.find("Angular_Speeds_List") is not None:
            speed_t, speed_ypr = _angle_series(doc, doc.nodes("Angular_Speeds_List/Angular_Speeds", aocs), epoch)

    psi_x, psi_y = _look_angles(doc, mission, ncols)
    mirror = doc.root.find("Data_Strip/Sensor_Configuration/Mirror_Position/STEP_COUNT")
    orientation = SpotOrientation(
        mission=mission, instrument=doc.text("INSTRUMENT", src).upper(),
        instrument_index=doc.integer("INSTRUMENT_INDEX", src), ncols=ncols, nrows=nrows, epoch=epoch,
        eph_t=eph_t, eph_pos=eph_pos, eph_vel=eph_vel, att_t=att_t, att_ypr=att_ypr,
        psi_x=psi_x, psi_y=psi_y, line_period=doc.number("LINE_PERIOD", stamp),
        centre_time=float(_seconds(centre, epoch)), centre_row=doc.number("SCENE_CENTER_LINE", stamp) - 0.5,
        speed_t=speed_t, speed_ypr=speed_ypr,
        sensor_code=(src.findtext("SENSOR_CODE") or "").strip(),
        mirror_step=None if mirror is None else doc.integer("Data_Strip/Sensor_Configuration/Mirror_Position/"
                                                            "STEP_COUNT"),
        corrections=Corrections(), name=(doc.root.findtext("Dataset_Id/DATASET_NAME") or path).strip())
    try:
        orientation.validate()
    except MetadataError as exc:
        raise MetadataError(f"{path}: {exc}") from None
    if image is not None and os.path.abspath(_dim_path(image)) == os.path.abspath(path):
        image = _own_raster(doc, path)
    if image is not None:
        check_image_size(orientation, image, path)
    return orientation


def _own_raster(doc, path):
    """The product's own raster (Data_Access DATA_FILE_PATH beside the metadata), if it exists."""
    href = doc.root.find("Data_Access/Data_File/DATA_FILE_PATH")
    raster = os.path.join(os.path.dirname(path), href.get("href", "")) if href is not None else ""
    return raster if os.path.isfile(raster) else None


def product_raster(path):
    """Path of the raster of the SPOT DIMAP product whose METADATA.DIM (or folder) is `path`: its
    Data_Access DATA_FILE_PATH beside the metadata, IMAGERY.TIF where it names none (whether it exists
    or not). MetadataError where the metadata cannot be read."""
    path = _dim_path(path)
    href = _Doc(path).root.find("Data_Access/Data_File/DATA_FILE_PATH")
    name = (href.get("href") if href is not None else "") or "IMAGERY.TIF"
    return os.path.join(os.path.dirname(path), name)


def check_image_size(orientation, image, path=""):
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
            "was cropped): use the METADATA.DIM delivered with this image")


# ---------------------------------------------------------------------------------------------
# Writing


def _num(value):
    """Shortest text that reads back to the same float (integral values without '.0')."""
    value = float(value)
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)


def _iso(epoch, seconds):
    """ISO UTC text of epoch + seconds: microseconds as in SPOT products, nanoseconds when needed."""
    ns = int(round(float(seconds) * 1e9))
    text = str(epoch + np.timedelta64(ns, "ns"))
    return text[:-3] if text.endswith("000") else text


def _sub(parent, tag, text=None, **attrib):
    e = ET.SubElement(parent, tag, attrib)
    if text is not None:
        e.text = str(text)
    return e


def _angles(parent, tag, epoch, t, ypr):
    for ti, (y, p, r) in zip(t, ypr):
        e = _sub(parent, tag)
        _sub(e, "TIME", _iso(epoch, ti))
        for k, v in zip(("YAW", "PITCH", "ROLL"), (y, p, r)):
            _sub(e, k, _num(v))
        _sub(e, "OUT_OF_RANGE", "N")


def _look_table(o):
    """Detector ids and angles to write: SPOT 1-4 tables that are linear keep only the end detectors."""
    ids = np.arange(1, o.ncols + 1)
    if o.mission <= 4:
        ends = np.array([0, o.ncols - 1])
        if all(np.array_equal(np.interp(ids, ids[ends], psi[ends]), psi) for psi in (o.psi_x, o.psi_y)):
            return ids[ends], o.psi_x[ends], o.psi_y[ends]
    return ids, o.psi_x, o.psi_y


def _frame(root, model, o):
    """Dataset_Frame, CRS, raster CS and Geoposition tie points: the corners at height 0."""
    corners = [(1, 1), (1, o.ncols), (o.nrows, o.ncols), (o.nrows, 1)]
    centre = (int(round(o.centre_row + 0.5)), o.ncols // 2 + 1)
    rows = np.array([c[0] for c in corners + [centre]], float) - 0.5
    cols = np.array([c[1] for c in corners + [centre]], float) - 0.5
    lon, lat = model.image_to_ground(cols, rows, np.zeros(rows.size))
    frame = _sub(root, "Dataset_Frame")
    for i, (row, col) in enumerate(corners + [centre]):
        v = _sub(frame, "Vertex" if i < 4 else "Scene_Center")
        for tag, value in (("FRAME_LON", _num(lon[i])), ("FRAME_LAT", _num(lat[i])),
                           ("FRAME_ROW", row), ("FRAME_COL", col)):
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
        for tag, value in (("TIE_POINT_CRS_X", lon[i]), ("TIE_POINT_CRS_Y", lat[i]), ("TIE_POINT_CRS_Z", 0.0),
                           ("TIE_POINT_DATA_X", col), ("TIE_POINT_DATA_Y", row)):
            _sub(tp, tag, _num(value))


def _source(root, o, sun):
    centre = o.epoch + np.timedelta64(int(round(o.centre_time * 1e9)), "ns")
    day, clock = str(centre.astype("datetime64[s]")).split("T")
    sources = _sub(_sub(root, "Dataset_Sources"), "Source_Information")
    _sub(sources, "SOURCE_TYPE", "SCENE")
    _sub(sources, "SOURCE_DESCRIPTION", f"SCENE {o.instrument}{o.instrument_index} {o.sensor_code}".strip())
    scene = _sub(sources, "Scene_Source")
    for tag, value in (("IMAGING_DATE", day), ("IMAGING_TIME", clock), ("MISSION", "SPOT"),
                       ("MISSION_INDEX", o.mission), ("INSTRUMENT", o.instrument),
                       ("INSTRUMENT_INDEX", o.instrument_index), ("SENSOR_CODE", o.sensor_code),
                       ("SCENE_PROCESSING_LEVEL", "1A")):
        _sub(scene, tag, value)
    if sun is not None:
        _sub(scene, "SUN_AZIMUTH", _num(sun[0]))
        _sub(scene, "SUN_ELEVATION", _num(sun[1]))


def _raster(root, o, nbits, nbands, data_file):
    dims = _sub(root, "Raster_Dimensions")
    for tag, value in (("NCOLS", o.ncols), ("NROWS", o.nrows), ("NBANDS", nbands)):
        _sub(dims, tag, value)
    enc = _sub(root, "Raster_Encoding")
    for tag, value in (("NBITS", nbits), ("BYTEORDER", "I"), ("COMPRESSION_NAME", "NONE"),
                       ("DATA_TYPE", "UNSIGNED")):
        _sub(enc, tag, value)
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


def _data_strip(root, o):
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
        if o.speed_t is not None:
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


def write_dimap(path, orientation, sun=None, nbits=8, nbands=1, data_file="IMAGERY.TIF"):
    """Write `orientation` as a SPOT level-1A METADATA.DIM (atomically) that `read_dimap` reads
    back unchanged and GDAL's DIMAP driver opens with its `data_file`.

    Dataset_Frame corners are computed with the rigorous model at height 0. `sun`: optional
    (azimuth, elevation) in degrees. Correction polynomials have no place in DIMAP: an orientation
    that carries any is refused (save adjusted models with sensors.save)."""
    from .spot import SpotModel
    o = orientation
    c = o.corrections
    if any(np.any(np.asarray(a) != 0) for a in (c.position, c.attitude, c.look)):
        raise InputError("DIMAP cannot hold correction polynomials; save the adjusted model with "
                         "sensors.save (the project's model file) instead")
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
    text = ('<?xml version="1.0" encoding="UTF-8"?>\n'
            + ET.tostring(root, encoding="unicode") + "\n")
    write_text(_dim_path(path), text)
