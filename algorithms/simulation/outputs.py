"""Writers of the simulator's products (all called inside one atomic folder, see scene.py):
geographic GeoTIFFs (EPSG:4326, heights ellipsoidal WGS 84), raw level-1A imagery, the point
candidates CSV and the truth JSON. Byte-for-byte reproducible (no timestamps)."""

import contextlib
import csv
import json

import numpy as np

from ..atomic import closing

GEOTIFF_OPTIONS = ["TILED=YES", "COMPRESS=DEFLATE", "ZLEVEL=1"]


ROWS = 256  # raster rows written at a time


def write_raster(path, array, grid, dtype, nodata=None, description="", metadata=None, convert=None):
    """North-up GeoTIFF of the grid array `array` (in memory or disk_array.DiskArray) on `grid`
    (EPSG:4326) as `dtype` (uint8 or float32), ROWS rows at a time (`convert` applied to each
    block first), tiled, DEFLATE, with overviews."""
    from osgeo import gdal

    from ..crs import wgs84

    gdal.UseExceptions()
    dtype = np.dtype(dtype)
    types = {np.dtype(np.uint8): gdal.GDT_Byte, np.dtype(np.float32): gdal.GDT_Float32}
    predictor = "PREDICTOR=3" if dtype == np.float32 else "PREDICTOR=2"
    with closing(
        gdal.GetDriverByName("GTiff").Create(
            str(path), grid.cols, grid.rows, 1, types[dtype], GEOTIFF_OPTIONS + [predictor]
        )
    ) as ds:
        ds.SetGeoTransform(grid.geotransform)
        ds.SetProjection(wgs84().ExportToWkt())
        band = ds.GetRasterBand(1)
        if nodata is not None:
            band.SetNoDataValue(nodata)
        band.SetDescription(description)
        for a in range(0, grid.rows, ROWS):
            block = np.asarray(array[a : min(a + ROWS, grid.rows)])
            band.WriteArray(np.asarray(convert(block) if convert else block, dtype=dtype), 0, a)
        band = None
        if metadata:
            ds.SetMetadata({k: str(v) for k, v in metadata.items()})
        ds.BuildOverviews("NEAREST" if dtype == np.uint8 and nodata == 0 else "AVERAGE", [2, 4, 8, 16])


@contextlib.contextmanager
def imagery_writer(path, ncols, nrows, bits):
    """Level-1A IMAGERY.TIF written block of lines by block: raw DN (uint8 for 8 bit, else uint16),
    no georeferencing (the geometry is in METADATA.DIM). Yields write(dn, first_row)."""
    from osgeo import gdal

    gdal.UseExceptions()
    dtype = gdal.GDT_Byte if bits == 8 else gdal.GDT_UInt16
    with closing(gdal.GetDriverByName("GTiff").Create(str(path), ncols, nrows, 1, dtype)) as ds:
        band = ds.GetRasterBand(1)
        yield lambda dn, row: band.WriteArray(dn, 0, row)
        band = None


def write_points(path, candidates):
    """CSV: id, lon, lat, h, then per image <name>_col, _row (true, GDAL pixel convention),
    <name>_col_meas, _row_meas (simulated measurement), <name>_blunder (1 if a gross error was
    injected)."""
    names = list(candidates.true)
    header = ["id", "lon", "lat", "h"]
    for name in names:
        header += [f"{name}_col", f"{name}_row", f"{name}_col_meas", f"{name}_row_meas", f"{name}_blunder"]
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for k in range(len(candidates)):
            row = [f"P{k + 1:03d}", f"{candidates.lon[k]:.10f}", f"{candidates.lat[k]:.10f}", f"{candidates.h[k]:.4f}"]
            for name in names:
                tc, tr = candidates.true[name][k]
                mc, mr = candidates.measured[name][k]
                row += [f"{tc:.5f}", f"{tr:.5f}", f"{mc:.5f}", f"{mr:.5f}", int(candidates.blunder[name][k])]
            writer.writerow(row)


def _plain(value):
    """JSON-ready copy: numpy arrays and scalars to lists and Python numbers."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def write_json(path, data):
    with open(path, "w", encoding="utf-8") as f:
        json.dump(_plain(data), f, indent=1, sort_keys=True)
        f.write("\n")
