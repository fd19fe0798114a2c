"""Writing rasters in a projected or geographic CRS: tiled, DEFLATE-compressed GeoTIFF with internal
overviews and nodata, written atomically (a cancel or a crash leaves nothing under the final name); a step's
outputs optionally as Cloud-Optimised GeoTIFF (raster_output: GDAL's COG driver copies the finished GeoTIFF with its
overviews, so that tiles and overviews lie in the order a reader over HTTP asks for them)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, NamedTuple

import numpy as np

from .. import progress
from ..atomic import atomic_path, closing
from ..errors import CancelledError
from ..progress import Feedback

#: nodata of the Float32 height and precision rasters
NODATA = -32767.0
OPTIONS = ["TILED=YES", "COMPRESS=DEFLATE", "PREDICTOR=3", "BIGTIFF=IF_SAFER"]
#: GDAL's COG driver: the GeoTIFF's own overviews (AVERAGE, overview_levels) kept, predictor by data type
COG_OPTIONS = ["COMPRESS=DEFLATE", "PREDICTOR=YES", "BIGTIFF=IF_SAFER", "OVERVIEWS=FORCE_USE_EXISTING"]


def overview_levels(shape, smallest=256):
    """Factors 2, 4, 8, ... until the overview's larger side is at most `smallest` cells."""
    levels, factor = [], 2
    while max(shape) / (factor // 2) > smallest:
        levels.append(factor)
        factor *= 2
    return levels


def write_float_raster(path, array, geotransform, srs, description="", metadata=None, feedback=None, overviews=True):
    """One Float32 band (NaN -> NODATA) with `geotransform` (GDAL's) and `srs` (osr.SpatialReference);
    without `overviews` for a tile that assemble_tiles joins to others."""
    values = np.where(np.isfinite(array), array, NODATA).astype(np.float32)
    return _write_band(path, values, geotransform, srs, description, metadata, feedback, overviews)


def write_code_raster(path, codes, geotransform, srs, description=""):
    """One Byte band of class codes (a mask), no nodata and no overviews (an average of codes means nothing)."""
    return _write_band(path, np.asarray(codes, np.uint8), geotransform, srs, description, None, None, False)


#: the GeoTIFF options of a band of codes (Byte: no floating-point predictor)
CODE_OPTIONS = ["TILED=YES", "COMPRESS=DEFLATE", "BIGTIFF=IF_SAFER"]


def _write_band(path, values, geotransform, srs, description, metadata, feedback, overviews):
    """`values` (float32: NODATA its nodata; uint8: codes) as one band of a GeoTIFF, atomically."""
    from osgeo import gdal

    gdal.UseExceptions()
    floating = values.dtype == np.float32
    kind, options = (gdal.GDT_Float32, OPTIONS) if floating else (gdal.GDT_Byte, CODE_OPTIONS)
    with atomic_path(path) as tmp:
        with closing(
            gdal.GetDriverByName("GTiff").Create(tmp, values.shape[1], values.shape[0], 1, kind, options)
        ) as ds:
            ds.SetGeoTransform(tuple(geotransform))
            ds.SetProjection(srs.ExportToWkt())
            if metadata:
                ds.SetMetadata({k: str(v) for k, v in metadata.items()})
            band = ds.GetRasterBand(1)
            if floating:
                band.SetNoDataValue(NODATA)
            band.SetDescription(description)
            band.WriteArray(values)
            band = None
            progress.step(feedback, 50)
            if overviews:
                ds.BuildOverviews("AVERAGE", overview_levels(values.shape))
        progress.step(feedback, 100)
    return path


class Frame(NamedTuple):
    """Where a raster lies: its GDAL `geotransform`, `size` (cols, rows) and `srs` (osr.SpatialReference)."""

    geotransform: Sequence[float]
    size: tuple[int, int]
    srs: Any


def assemble_tiles(
    tiles: Iterable[str],
    path: str,
    frame: Frame,
    options: Sequence[str] = OPTIONS,
    description: str | None = None,
    metadata: dict[str, Any] | None = None,
    overviews: str | None = "AVERAGE",
    feedback: Feedback | None = None,
) -> str:
    """Write the GeoTIFF `tiles` (one data type, bands and nodata; together they cover parts of the raster
    of `frame`) as one GeoTIFF at `path` (a temporary name: the caller renames it) with creation `options`
    and overviews (overview_levels) resampled by GDAL's `overviews` method (None: no overviews; NEAREST for codes,
    which an average would mix): a VRT translated and its overviews
    built by GDAL in blocks, so memory follows GDAL's cache, not the raster. Cells no tile covers are the
    tiles' nodata. CancelledError when `feedback` cancels."""
    from osgeo import gdal

    gdal.UseExceptions()
    geotransform, size, srs = frame
    x0, dx, _, y0, _, dy = geotransform
    bounds = (x0, y0 + size[1] * dy, x0 + size[0] * dx, y0)
    vrt = gdal.BuildVRT("", list(tiles), outputBounds=bounds, xRes=dx, yRes=-dy)
    try:
        vrt.SetProjection(srs.ExportToWkt())
        if metadata:
            vrt.SetMetadata({k: str(v) for k, v in metadata.items()})
        with closing(
            gdal.Translate(
                path,
                vrt,
                format="GTiff",
                creationOptions=list(options),
                callback=progress.gdal_callback(progress.scaled(feedback, 0, 60)),
            )
        ) as ds:
            if description is not None:
                ds.GetRasterBand(1).SetDescription(description)
            levels = overview_levels((size[1], size[0])) if overviews else []
            if levels:
                ds.BuildOverviews(
                    overviews, levels, callback=progress.gdal_callback(progress.scaled(feedback, 60, 100))
                )
    except RuntimeError:
        if feedback is not None and feedback.isCanceled():
            raise CancelledError("cancelled by the user") from None
        raise
    finally:
        vrt = None
    progress.step(feedback, 100)
    return path


def to_cog(path: str, feedback: Feedback | None = None) -> str:
    """Rewrite the finished GeoTIFF at `path` (a temporary name) as a Cloud-Optimised GeoTIFF (GDAL's COG driver,
    COG_OPTIONS: its overviews, metadata, band descriptions and nodata kept), in place."""
    from osgeo import gdal

    gdal.UseExceptions()
    cog = f"{path}.cog"
    try:
        with closing(
            gdal.Translate(
                cog,
                path,
                format="COG",
                creationOptions=COG_OPTIONS,
                callback=progress.gdal_callback(feedback),
            )
        ):
            pass
        os.replace(cog, path)
    except RuntimeError:
        with contextlib.suppress(OSError):
            os.unlink(cog)
        if feedback is not None and feedback.isCanceled():
            raise CancelledError("cancelled by the user") from None
        raise
    progress.step(feedback, 100)
    return path


@contextlib.contextmanager
def raster_outputs(
    paths: Sequence[str | None], cog: bool = False, feedback: Feedback | None = None
) -> Iterator[list[str | None]]:
    """atomic_path for a step's raster outputs (None: one not asked for): yields their temporary names to write the
    GeoTIFFs to; when the body succeeds, each is made a Cloud-Optimised GeoTIFF where `cog` (to_cog), all before any
    is renamed: a failure or a cancel while any of them is written leaves every target as it was. The renames then
    follow one another, the last of `paths` first (each checked again just before, atomic_path): not one atomic step
    across files, so a rename refused by the file system at that moment can leave the outputs before it new and the
    others old."""
    with contextlib.ExitStack() as stack:
        temps = [stack.enter_context(atomic_path(path)) if path else None for path in paths]
        yield temps
        if cog:
            written = [tmp for tmp in temps if tmp]
            for k, tmp in enumerate(written):
                to_cog(tmp, progress.scaled(feedback, 100.0 * k / len(written), 100.0 * (k + 1) / len(written)))


@contextlib.contextmanager
def raster_output(path: str, cog: bool = False, feedback: Feedback | None = None) -> Iterator[str]:
    """raster_outputs of one raster: yields its temporary name."""
    with raster_outputs([path], cog, feedback) as (tmp,):
        yield tmp  # type: ignore[misc]
