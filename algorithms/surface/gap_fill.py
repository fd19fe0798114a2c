"""Gap filling of a per-cell DEM, always flagged in a mask raster.

Model: GDAL's FillNodata (GDALFillNodata): each gap cell within `max_distance` cells of measured ones gets the
inverse-distance weighted mean of the nearest measured cell found in each of the four quadrant directions
(no smoothing passes); farther cells stay gaps. Only gaps the measured cells enclose are filled: a filled cell
must lie in the morphological closing of the measured cells by a square of 2 d + 1 cells (d = max_distance
rounded up: a dilation by d, then an erosion by d), so a fill never reaches past the edge of the cloud (beyond
the images' overlap, into a lake or a forest the matching left) but closes holes and inlets up to 2 d cells
wide. The mask raster (Byte, the DEM's grid) says what each cell
is: 0 measured (the per-cell median of its own points), 2 measured from the points of the cells around it
(cell_dem's radius; from the ring raster, where given), 1 filled, 255 still a gap. Both rasters are read and
written in strips of rows, and FillNodata works by scanlines, so memory follows the DEM's width, not its
area. The DEM's overviews are rebuilt.

studies/dense_fusion.py measures interpolation against the dense points a cell without refined ones has.

Failure modes: CancelledError through the feedback (the caller's atomic outputs then leave nothing).

Reference: GDAL, gdal_fillnodata (alg/rasterfill.cpp)."""

import numpy as np
from scipy import ndimage

from .. import progress
from ..atomic import closing
from ..errors import CancelledError
from .geotiff import overview_levels

MEASURED, FILLED, NEIGHBOURS, GAP = 0, 1, 2, 255
STRIP = 512  # rows read at a time


def _strips(rows):
    return [(r, min(STRIP, rows - r)) for r in range(0, rows, STRIP)]


def _enclosed(mask_band, row, count, reach):
    """Rows row ... row + count of the closing of the measured cells (mask values other than GAP; module
    docstring) by a square of 2 reach + 1 cells, from the strip widened by 2 reach rows on each side (the
    filled cells of the strips before are not measured: FILLED is told apart from MEASURED and NEIGHBOURS)."""
    rows, cols = mask_band.YSize, mask_band.XSize
    top, bottom = max(0, row - 2 * reach), min(rows, row + count + 2 * reach)
    flags = mask_band.ReadAsArray(0, top, cols, bottom - top)
    measured = ((flags == MEASURED) | (flags == NEIGHBOURS)).astype(np.uint8)
    size = 2 * reach + 1
    closed = ndimage.minimum_filter(
        ndimage.maximum_filter(measured, size, mode="constant", cval=0), size, mode="nearest"
    )
    return closed[row - top : row - top + count] > 0


def fill_gaps(path, mask_path, max_distance, feedback=None, rings=None):
    """Fill the gaps of the single-band GeoTIFF `path` (in place) within `max_distance` cells (0: none) and
    write the mask raster `mask_path` (module docstring); `rings`: the GeoTIFF of cell_dem's rings on the same
    grid, or None. Returns the number of cells filled."""
    from osgeo import gdal

    gdal.UseExceptions()
    with closing(gdal.Open(str(path), gdal.GA_Update)) as ds:
        band = ds.GetRasterBand(1)
        cols, rows = ds.RasterXSize, ds.RasterYSize
        driver = gdal.GetDriverByName("GTiff")
        with closing(
            driver.Create(str(mask_path), cols, rows, 1, gdal.GDT_Byte, ["TILED=YES", "COMPRESS=DEFLATE"])
        ) as mask:
            mask.SetGeoTransform(ds.GetGeoTransform())
            mask.SetProjection(ds.GetProjection())
            out = mask.GetRasterBand(1)
            out.SetNoDataValue(GAP)
            out.SetDescription("0 measured, 2 measured from the cells around, 1 filled, 255 gap")
            ring_ds = gdal.Open(str(rings)) if rings else None
            for r, n in _strips(rows):
                valid = band.GetMaskBand().ReadAsArray(0, r, cols, n) > 0
                around = ring_ds.GetRasterBand(1).ReadAsArray(0, r, cols, n) > 0 if ring_ds else False
                out.WriteArray(np.where(valid, np.where(around, NEIGHBOURS, MEASURED), GAP).astype(np.uint8), 0, r)
            ring_ds = None
            progress.step(feedback, 10)
            filled = 0
            if max_distance:
                try:
                    gdal.FillNodata(
                        band,
                        None,
                        float(max_distance),
                        0,
                        callback=progress.gdal_callback(progress.scaled(feedback, 10, 80)),
                    )
                except RuntimeError:
                    if feedback is not None and feedback.isCanceled():
                        raise CancelledError("cancelled by the user") from None
                    raise
                reach = int(np.ceil(max_distance))
                nodata = band.GetNoDataValue()
                for r, n in _strips(rows):
                    valid = band.GetMaskBand().ReadAsArray(0, r, cols, n) > 0
                    flags = out.ReadAsArray(0, r, cols, n)
                    new = valid & (flags == GAP)
                    outside = new & ~_enclosed(out, r, n, reach)
                    if outside.any():
                        heights = band.ReadAsArray(0, r, cols, n)
                        heights[outside] = nodata if nodata is not None else np.nan
                        band.WriteArray(heights, 0, r)
                    new &= ~outside
                    filled += int(new.sum())
                    flags[new] = FILLED
                    out.WriteArray(flags, 0, r)
        levels = overview_levels((rows, cols))
        if levels:
            ds.BuildOverviews("AVERAGE", levels, callback=progress.gdal_callback(progress.scaled(feedback, 80, 100)))
    return filled
