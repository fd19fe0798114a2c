"""A DEM raster stored for reading by windows: its ellipsoidal heights on a WGS 84 longitude/latitude
grid (dem.Dem's conventions) in a float64 `.npy` file of a work folder (disk_array.DiskArray), written
and read by bands of ROWS rows, so that memory follows the band or the window, never the raster.

Reading (store_dem; read_dem reads a DEM into memory this way):
1. the raster's band 1 as float64, its own nodata and a declared void value (`nodata`, such as SRTM's
   -32768 in a file that does not flag its voids) as NaN; implausible heights (dem.implausible_heights)
   counted over all bands, reported and used as given;
2. a raster in another CRS is copied so (a GeoTIFF in the work folder) and warped by GDAL to
   EPSG:4326, bilinear, to another GeoTIFF there (GDAL warps in chunks within its memory limit);
3. orthometric EGM96 heights (vertical 'egm96') get the undulation N (h = H + N, PROJ) computed on a
   lattice of at most crs.UNDULATION_NODES x UNDULATION_NODES cells over the grid and interpolated
   bilinearly (N varies over tens of kilometres).

A StoredDem answers what the steps ask of a DEM without holding it: the Dem of a window (dem.dem_window:
its heights are the whole DEM's there), heights at points (each block of BLOCK x BLOCK cells read once,
tiling.cell_blocks), the ground points of image rays (each ray in the window its height range can reach),
and the height range of a box of cells.

Failure modes: InputError (a file that cannot be opened or has no CRS, a grid that is not north-up or
holds no height, unknown vertical), StorageError (the work folder's disk)."""

import contextlib
import math
import os
from dataclasses import dataclass

import numpy as np

from .atomic import close_dataset, closing, storage_error
from .crs import undulation_rows, wgs84
from .dem import Dem, ImplausibleTally, check_grid, dem_window, grid_bounds, nodata_as_nan
from .disk_array import DiskArray
from .errors import GeometryError, InputError
from .geodesy import flat_points
from .tiling import cell_blocks

#: rows of a band read or written at a time
ROWS = 128
#: side (cells) of the blocks StoredDem.height reads
BLOCK = 1024
#: DEM vertical references store_dem converts from
VERTICAL = ("ellipsoidal", "egm96")


@dataclass
class StoredDem:
    """Ellipsoidal heights on a lon/lat grid in the .npy file `path` (module docstring)."""

    path: str
    geotransform: tuple
    shape: tuple
    height_range: tuple  # (min, max) of the valid heights
    implausible: str = None  # dem.implausible_heights' warning of the heights as read

    @property
    def bounds(self):
        """(lon_min, lat_min, lon_max, lat_max) of the grid's outer cell edges."""
        return grid_bounds(self.geotransform, self.shape)

    def window(self, bounds):
        """The Dem of the cells over lon/lat `bounds` and one more around (dem.dem_window)."""
        return dem_window(DiskArray.existing(self.path), self.geotransform, self.height_range, bounds)

    def whole(self):
        """The whole grid as a Dem in memory (for a small DEM)."""
        dem = Dem(DiskArray.existing(self.path)[:, :], self.geotransform)
        dem.implausible = self.implausible
        return dem

    def height(self, lon, lat):
        """Bilinear height at (lon, lat) (arrays or scalars), as dem.Dem.height: the points of each block
        of BLOCK x BLOCK cells from a window of that block's cells."""
        (lon, lat), shape, scalar = flat_points(lon, lat)
        out = np.full(lon.size, np.nan)  # off the grid: no height
        lon0, dlon, _, lat0, _, dlat = self.geotransform
        for sel in cell_blocks((lon - lon0) / dlon, (lat - lat0) / dlat, self.shape, BLOCK):
            window = self.window((lon[sel].min(), lat[sel].min(), lon[sel].max(), lat[sel].max()))
            out[sel] = window.height(lon[sel], lat[sel])
        return float(out[0]) if scalar else out.reshape(shape)

    def ground(self, model, col, row):
        """(lon, lat, h) where the rays of image points (col, row) of sensor `model` meet the DEM
        (model.image_to_dem), each ray in the window of the cells under it between the DEM's lowest and
        highest heights, where image_to_dem searches."""
        (c, r), shape, _ = flat_points(col, row)
        low, high = self.height_range
        ends = [model.image_to_ground(c, r, np.full(c.size, h)) for h in (low - 1.0, high + 1.0)]
        lon, lat, h = (np.empty(c.size) for _ in range(3))
        for k in range(c.size):
            lons, lats = (ends[0][0][k], ends[1][0][k]), (ends[0][1][k], ends[1][1][k])
            if not np.isfinite(lons + lats).all():
                raise GeometryError(
                    f"the line of sight of image point ({c[k]:.1f}, {r[k]:.1f}) has no ground "
                    "position: is the orientation complete for the whole image?"
                )
            window = self.window((min(lons), min(lats), max(lons), max(lats)))
            lon[k], lat[k], h[k] = (
                float(np.asarray(v).ravel()[0]) for v in model.image_to_dem(c[k : k + 1], r[k : k + 1], window)
            )
        return lon.reshape(shape), lat.reshape(shape), h.reshape(shape)

    def cells_range(self, rows, cols):
        """(min, max) of the valid heights of the cells rows[0]:rows[1], cols[0]:cols[1] (NaN, NaN where none)."""
        array, low, high = DiskArray.existing(self.path), np.inf, -np.inf
        for r0 in range(rows[0], rows[1], ROWS):
            band = array[r0 : min(r0 + ROWS, rows[1]), cols[0] : cols[1]]
            if np.isfinite(band).any():
                low, high = min(low, float(np.nanmin(band))), max(high, float(np.nanmax(band)))
        return (low, high) if low <= high else (math.nan, math.nan)


def _open(path):
    from osgeo import gdal

    gdal.UseExceptions()
    try:
        ds = gdal.Open(str(path))
    except RuntimeError as exc:
        if not os.path.exists(path):
            raise InputError(f"cannot open DEM {path}: the file does not exist; check the path") from None
        raise InputError(f"cannot open DEM {path}: GDAL does not read it as a raster ({exc})") from exc
    if ds.GetSpatialRef() is None:
        raise InputError(
            f"the DEM {path} has no coordinate reference system, so where its cells lie is unknown: "
            f"assign the CRS of its coordinates, e.g. 'gdal_edit.py -a_srs EPSG:4326 {path}' for "
            "longitude/latitude in degrees (or the EPSG code of its map projection), and run again"
        )
    return ds


def _bands(ds, *nodata):
    """(first row, float64 heights) of band 1 of `ds` by ROWS rows, the `nodata` values (None: none) as NaN."""
    band = ds.GetRasterBand(1)
    for r0 in range(0, ds.RasterYSize, ROWS):
        yield r0, nodata_as_nan(band.ReadAsArray(0, r0, ds.RasterXSize, min(ROWS, ds.RasterYSize - r0)), *nodata)


def _warped(ds, nodata, work, tally):
    """`ds` (not in EPSG:4326) with its nodata as NaN, copied to the work folder and warped bilinearly to
    EPSG:4326 by GDAL; returns the path of the warped GeoTIFF. StorageError where a write fails."""
    from osgeo import gdal

    source, target = os.path.join(work, "dem-source.tif"), os.path.join(work, "dem-wgs84.tif")
    options = ["TILED=YES", "BIGTIFF=IF_SAFER"]
    try:
        with closing(
            gdal.GetDriverByName("GTiff").Create(source, ds.RasterXSize, ds.RasterYSize, 1, gdal.GDT_Float64, options)
        ) as copy:
            copy.SetGeoTransform(ds.GetGeoTransform())
            copy.SetSpatialRef(ds.GetSpatialRef())
            copy.GetRasterBand(1).SetNoDataValue(float("nan"))
            for r0, heights in _bands(ds, ds.GetRasterBand(1).GetNoDataValue(), nodata):
                copy.GetRasterBand(1).WriteArray(tally.add(heights), 0, r0)
        close_dataset(
            gdal.Warp(
                target,
                source,
                format="GTiff",
                dstSRS="EPSG:4326",
                resampleAlg="bilinear",
                outputType=gdal.GDT_Float64,
                dstNodata=float("nan"),
                creationOptions=options,
            )
        )
    except (RuntimeError, OSError) as exc:
        raise storage_error(exc, target, "the stored DEM") from None
    finally:
        with contextlib.suppress(OSError):
            os.remove(source)
    return target


def store_dem(path, work, nodata=None, vertical="ellipsoidal"):
    """The DEM raster `path` stored in the folder `work` (module docstring); returns its StoredDem."""
    if vertical not in VERTICAL:
        raise InputError(f"the DEM heights are {' or '.join(VERTICAL)}, not {vertical!r}")
    ds = _open(path)
    tally, warped = ImplausibleTally(), None
    if ds.GetSpatialRef().IsSame(wgs84(), ["IGNORE_DATA_AXIS_TO_SRS_AXIS_MAPPING=YES"]):
        grid, bands = ds, ((r0, tally.add(h)) for r0, h in _bands(ds, ds.GetRasterBand(1).GetNoDataValue(), nodata))
    else:
        from osgeo import gdal

        warped = _warped(ds, nodata, work, tally)
        grid = gdal.Open(warped)
        bands = _bands(grid)
    shape, geotransform = (grid.RasterYSize, grid.RasterXSize), grid.GetGeoTransform()
    geotransform = check_grid(shape, geotransform)
    undulation = undulation_rows(shape, geotransform) if vertical == "egm96" else None
    out = DiskArray(os.path.join(work, "dem.npy"), shape, np.float64, "the stored DEM")
    low, high = np.inf, -np.inf
    for r0, heights in bands:
        if undulation is not None:
            heights += undulation(r0, len(heights))
        out[r0 : r0 + len(heights)] = heights
        if np.isfinite(heights).any():
            low, high = min(low, float(np.nanmin(heights))), max(high, float(np.nanmax(heights)))
    grid = bands = None
    if warped:
        os.remove(warped)
    if not low <= high:
        raise InputError("the DEM holds no valid height (all cells are nodata)")
    return StoredDem(out.path, geotransform, shape, (low, high), tally.warning(f"the DEM {path}"))


def read_dem(path, nodata=None):
    """The whole DEM raster `path` as a dem.Dem in memory, read as store_dem reads it (ellipsoidal heights;
    other CRSs warped bilinearly to EPSG:4326; its nodata and `nodata`, a declared void value, as NaN;
    `implausible` set), by way of a temporary folder of the system (a StorageError where it is full).
    InputError where the file cannot be opened or has no CRS. For a large raster, use store_dem's windows."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="pushbroom-dem-") as work:
        return store_dem(path, work, nodata).whole()


def as_stored(dem, work):
    """`dem` as a StoredDem: itself, or a dem.Dem in memory stored in the folder `work` (stored_copy)."""
    return dem if isinstance(dem, StoredDem) else stored_copy(dem, work)


def stored_copy(dem, work):
    """A StoredDem of the Dem `dem` (in memory) in the folder `work`."""
    out = DiskArray(os.path.join(work, "dem.npy"), dem.shape, np.float64, "a copy of the DEM")
    for r0 in range(0, dem.shape[0], ROWS):
        out[r0 : r0 + ROWS] = dem.heights[r0 : r0 + ROWS]
    return StoredDem(out.path, dem.geotransform, dem.shape, dem.height_range, dem.implausible)
