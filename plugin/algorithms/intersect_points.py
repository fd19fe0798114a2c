"""pushbroom:intersectpoints — object points of the block's mass or tie points by forward
intersection (K 3.5.1; algorithms/surface/intersection.py), written as a point cloud (LAS/LAZ or a
GeoPackage point layer; algorithms/surface/pointcloud.py)."""
import numpy as np
from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputNumber,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
)

from ...algorithms import progress
from ...algorithms.adjustment.observations import IMAGE_SIGMA
from ...algorithms.block import Block
from ...algorithms.errors import InputError
from ...algorithms.height_range import mean_height
from ...algorithms.surface import intersection, pointcloud
from ..styles import load_styled
from .base import PushbroomAlgorithm

Number = QgsProcessingParameterNumber
KINDS = (("mass_points", "Mass points (pushbroom:matchpoints)"),
         ("tie_points", "Tie points (pushbroom:selecttiepoints)"))


class IntersectPoints(PushbroomAlgorithm):
    NAME = "intersectpoints"
    DISPLAY_NAME = "Intersect points (point cloud)"
    GROUP = "Surface"
    GROUP_ID = "surface"
    HELP = ("Object points of the block's mass points or tie points by forward intersection with the block's "
            "current sensor models (Kornus et al. 2006, 3.5.1): per point a least-squares adjustment of its image "
            "coordinates (two rays: 4 observations for 3 unknowns; three rays: 6), which gives its precision "
            "from the image sigma (a priori) and from its residuals (sigma0). The points are written in the "
            "output CRS (default: the block's UTM zone) with z = WGS 84 ellipsoidal height to a LAS or LAZ "
            "file (extra dimensions point_id, group, rho, rays, sigma_h, sigma0; LAZ needs the Python package "
            "lazrs) or, up to 100 000 points, a GeoPackage (3-D points, same fields; loaded as a layer). Points "
            "that cannot be intersected (one ray, outside an image or a model's domain, parallel rays, no "
            "convergence) are left out and counted in the log, which also lists per point group the count and "
            "the median sigmas.")

    def initAlgorithm(self, config=None):
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block", extension="gpkg"))
        self.addParameter(QgsProcessingParameterEnum("POINTS", "Points", [text for _, text in KINDS], defaultValue=0))
        self.addParameter(QgsProcessingParameterCrs("CRS", "Output CRS (empty: the block's UTM zone)", None,
                                                    optional=True))
        self.addAdvancedParameters([
            Number("SIGMA", "Sigma of the image coordinates (px)", Number.Double, IMAGE_SIGMA, minValue=1e-6),
            Number("MAX_ITERATIONS", "Maximum iterations per point", Number.Integer, 10, minValue=1),
        ])
        self.addParameter(QgsProcessingParameterFileDestination(
            "OUTPUT", "Point cloud", "LAS files (*.las);;LAZ files (*.laz);;GeoPackage (*.gpkg)"))
        self.addOutput(QgsProcessingOutputVectorLayer("LAYER", "Point layer (GeoPackage output)",
                                                      QgsProcessing.TypeVectorPoint))
        self.addOutput(QgsProcessingOutputNumber("COUNT", "Points written"))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, "BLOCK", context)
        blk = Block(path)
        kind = KINDS[self.parameterAsEnum(parameters, "POINTS", context)][0]
        multi = blk.points(kind)
        known = {r["id"] for r in blk.images()}
        ids = [int(i) for i in multi.image_ids()]
        if not ids:
            raise InputError(f"the block's {kind.replace('_', ' ')} have no image measurements")
        if set(ids) - known:
            raise InputError(f"the {kind.replace('_', ' ')} refer to image ids {sorted(set(ids) - known)} which the "
                             "block does not have: run the matching step again")
        models = {i: blk.model(i) for i in ids}
        heights = blk.height_range()
        obs = multi.observations
        result = intersection.intersect(
            models, obs["image_id"], obs["point_id"], obs["col"], obs["row"],
            sigma=self.parameterAsDouble(parameters, "SIGMA", context),
            h0=None if heights is None else mean_height(heights),
            max_iter=self.parameterAsInt(parameters, "MAX_ITERATIONS", context),
            feedback=progress.scaled(feedback, 0, 80))
        pos = np.searchsorted(multi.points["id"], result.point).clip(max=max(len(multi) - 1, 0))
        if len(multi) == 0 or np.any(multi.points["id"][pos] != result.point):
            raise InputError(f"the stored {kind.replace('_', ' ')} have observations of unknown points: run the "
                             "matching step again")
        group = multi.points["group"][pos]
        feedback.pushInfo(f"{len(result)} {kind.replace('_', ' ')}: "
                          + ", ".join(f"{name} {n}" for name, n in result.status_counts().items()))
        feedback.pushInfo("per point group (a priori sigmas in m from the image sigma; sigma0 a posteriori):\n"
                          + intersection.format_summary(intersection.summary_rows(result, group)))
        ok = result.ok
        if not ok.any():
            raise InputError(f"none of the {len(result)} points could be intersected "
                             f"({result.status_counts()}): check the block's sensor models and the points")
        crs = self.parameterAsCrsDefinition(parameters, "CRS", context) or blk.info().get("default_crs")
        out = self.parameterAsFileOutput(parameters, "OUTPUT", context)
        fields = pointcloud.cloud_fields(result, group=group, rho=multi.points["rho_min"][pos])
        out, srs, fmt = pointcloud.write_point_cloud(out, result.lon[ok], result.lat[ok], result.h[ok], fields, crs=crs,
                                                     feedback=progress.scaled(feedback, 80, 100))
        message = f"{int(ok.sum())} points written to {out} ({srs.GetName()}; z ellipsoidal height)"
        feedback.pushInfo(message)
        blk.update_info({}, step="intersectpoints", message=message)
        results = {"OUTPUT": out, "COUNT": int(ok.sum())}
        if fmt == "gpkg":
            results["LAYER"] = f"{out}|layername={pointcloud.GPKG_LAYER}"
            load_styled(context, results["LAYER"], "Object points", "LAYER", "points_by_group.qml")
        return results
