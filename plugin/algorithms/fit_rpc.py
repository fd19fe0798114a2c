"""pushbroom:fitrpc — RPC00B fitted to the block's sensor models over a terrain-independent cube
(Kornus et al. 2006, 3.5.2; algorithms/sensors/rpc_fit.py), written as _RPC.TXT files GDAL reads."""
import numpy as np
from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputMultipleLayers, QgsProcessingParameterBoolean,
                       QgsProcessingParameterFile, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterFolderDestination, QgsProcessingParameterNumber,
                       QgsProcessingParameterString)

from ...algorithms import progress
from ...algorithms.block import Block
from ...algorithms.adjustment import report
from ...algorithms.errors import InputError
from ...algorithms.sensors import rpc_fit
from ...algorithms.surface.intersection import height_differences
from .base import PushbroomAlgorithm
from ...algorithms.height_range import mean_height

Number = QgsProcessingParameterNumber


def selected_images(rows, name):
    """The block's image rows, or the one called `name` (empty: all)."""
    name = (name or "").strip()
    if not name:
        return list(rows)
    chosen = [r for r in rows if r["name"] == name]
    if not chosen:
        raise InputError(f"image {name} is not in the block; it has {', '.join(r['name'] for r in rows)}")
    return chosen


def cube_heights(block_path, h_min, h_max):
    """(min, max) heights of the cube: both given, or the block's terrain height range widened by a margin
    (rpc_fit.default_height_range)."""
    if h_min is not None and h_max is not None:
        return h_min, h_max
    if h_min is not None or h_max is not None:
        raise InputError("give both the lowest and the highest height of the RPC cube, or neither (then the "
                         "block's terrain height range is used, widened by a margin)")
    terrain = Block(block_path).height_range()
    if terrain is None:
        raise InputError(f"block {block_path} records no terrain height range: give the lowest and highest "
                         "heights of the RPC cube")
    return rpc_fit.default_height_range(terrain)


def rpc_height_check(block_path, rpcs):
    """The summary of surface.intersection.height_differences on the block's tie points, when the
    block has tie points and RPCs were fitted for all their images ("" otherwise)."""
    blk = Block(block_path)
    if "tie_points" not in blk.info():
        return ""
    obs = blk.points("tie_points").observations
    images = set(np.unique(obs["image_id"]).tolist())
    if not images or not images <= set(rpcs):
        return ""
    rigorous = {i: blk.model(i) for i in images}
    return height_differences(rigorous, {i: rpcs[i] for i in images}, obs["image_id"], obs["point_id"],
                              obs["col"], obs["row"], h0=mean_height(blk.height_range())).summary()


class FitRpc(PushbroomAlgorithm):
    NAME = "fitrpc"
    DISPLAY_NAME = "Fit RPC"
    GROUP = "Adjustment"
    GROUP_ID = "adjustment"
    HELP = ("Fits rational polynomial coefficients (RPC00B, degree 3 over 3) to the sensor model the block holds "
            "for each image, supplied or adjusted (Kornus et al. 2006, 3.5.2): a terrain-independent cube of "
            "11 x 11 image points over the whole image times 11 heights over the block's terrain height range "
            "(widened by a margin) or the given range; the rational functions are linearised and fitted by "
            "iteratively reweighted least squares with a damped denominator. Where a denominator would come "
            "near zero over the image, a plain cubic polynomial is used, and the report says so. The RPC is "
            "written as <image stem>_RPC.TXT beside each image raster (GDAL then reads it with the raster) or, "
            "with an output folder, as <image name>_RPC.TXT there; an existing file, such as the RPC an image "
            "came with, is only replaced with 'Overwrite'. The report gives the RMS and maximum errors in "
            "pixels against the block's model on the cube and on independent validation points (a grid twice "
            "as dense, shifted by half its step).")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block", extension="gpkg"))
        self.addParameter(QgsProcessingParameterString("IMAGE", "Image name (empty: every image of the block)", "",
                                                       optional=True))
        self.addParameter(Number("MIN_HEIGHT", "Lowest ellipsoidal height of the cube (m; empty: the block's "
                                 "terrain height range and a margin)", Number.Double, None, optional=True))
        self.addParameter(Number("MAX_HEIGHT", "Highest ellipsoidal height of the cube (m; empty: the block's "
                                 "terrain height range and a margin)", Number.Double, None, optional=True))
        self.addParameter(QgsProcessingParameterBoolean("OVERWRITE", "Overwrite existing _RPC.TXT files", False))
        grid, _, levels = rpc_fit.DEFAULT_GRID
        self.addAdvancedParameters([
            Number("GRID", "Image grid points along columns and rows", Number.Integer, grid, minValue=4),
            Number("HEIGHT_LEVELS", "Height levels", Number.Integer, levels, minValue=4),
        ])
        self.addParameter(QgsProcessingParameterFolderDestination(
            "OUTPUT_FOLDER", "Output folder (empty: beside each image raster)", optional=True,
            createByDefault=False))
        self.addParameter(QgsProcessingParameterFileDestination("REPORT", "Report", "HTML files (*.html)",
                                                                optional=True))
        self.addOutput(QgsProcessingOutputMultipleLayers("FILES", "RPC files (_RPC.TXT)"))
        self.addOutput(QgsProcessingOutputFile("BLOCK", "Block (updated; chains the next step in a model)"))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, "BLOCK", context)
        blk = Block(path)
        rows = selected_images(blk.images(), self.parameterAsString(parameters, "IMAGE", context))

        heights = cube_heights(path, self.parameterAsOptionalDouble(parameters, "MIN_HEIGHT", context),
                               self.parameterAsOptionalDouble(parameters, "MAX_HEIGHT", context))
        n = self.parameterAsInt(parameters, "GRID", context)
        grid = (n, n, self.parameterAsInt(parameters, "HEIGHT_LEVELS", context))
        folder = self.parameterAsString(parameters, "OUTPUT_FOLDER", context) or None
        overwrite = self.parameterAsBool(parameters, "OVERWRITE", context)
        destinations = []
        for row in rows:
            if folder is None and not row["image_path"]:
                raise InputError(f"image {row['name']} has no raster path in the block: give an output folder")
            destination = rpc_fit.rpc_txt_path(row["image_path"], folder, row["name"])
            rpc_fit.check_destination(destination, overwrite)
            destinations.append(destination)
        fitted = []
        for k, row in enumerate(rows):
            progress.step(feedback, 95.0 * k / len(rows), f"fitting the RPC of {row['name']}")
            fitted.append(rpc_fit.fit_rpc(blk.model(row["id"]), heights, grid,
                                          feedback=progress.scaled(feedback, 95.0 * k / len(rows),
                                                                   95.0 * (k + 1) / len(rows))))
        progress.step(feedback, 95.0)
        entries = []
        for row, (rpc, fit), destination in zip(rows, fitted, destinations):
            written = rpc_fit.write_fitted_rpc(rpc, destination, overwrite)
            entries.append((row["name"], written, fit))
            if folder is None and not rpc_fit.raster_reads(row["image_path"], rpc):
                feedback.pushWarning(f"GDAL does not read {written} with {row['image_path']} (the raster carries "
                                     "other RPC metadata it prefers, or cannot be opened): load the _RPC.TXT itself")
        text = rpc_fit.report_text(entries)
        comparison = rpc_height_check(path, {row["id"]: rpc for row, (rpc, _) in zip(rows, fitted)})
        if comparison:
            text += "\n\nRPC minus rigorous object points of the block's tie points (Kornus et al. 2006, Table 5): " \
                    + comparison
        feedback.pushInfo(text)
        blk.update_info({}, step="fitrpc",
                        message="; ".join(f"{name}: {written}" for name, written, _ in entries))
        out = {"BLOCK": path, "FILES": [written for _, written, _ in entries]}
        if folder:
            out["OUTPUT_FOLDER"] = folder
        destination = self.parameterAsFileOutput(parameters, "REPORT", context)
        if destination:
            out["REPORT"] = report.write_html(destination, f"RPC fit for {path}", text)
        return out
