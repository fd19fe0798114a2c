"""pushbroom:matchpoints — dense image points by region-growing least-squares matching in the
three combinations of paper K 3.3 (algorithms/matching/combinations.py)."""
from qgis.core import (QgsProcessing, QgsProcessingOutputFile, QgsProcessingOutputVectorLayer,
                       QgsProcessingParameterBoolean, QgsProcessingParameterEnum, QgsProcessingParameterFile,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber,
                       QgsProcessingParameterString)

from ...algorithms import block
from ...algorithms.height_range import height_range, mean_height
from ...algorithms.matching import combinations, hierarchical, points
from ...algorithms.matching.params import GrowParams
from ..styles import load_styled
from .base import PushbroomAlgorithm

Number = QgsProcessingParameterNumber
#: seed choices: (label, use the block's tie points, automatic seeds)
SEED_SOURCES = (("Automatic: interest points matched along the path predicted by the sensor models", False, True),
                ("The block's tie points (pushbroom:selecttiepoints)", True, False),
                ("Both: the block's tie points and automatic seeds", True, True))


#: matching strategies: (label, engine key)
STRATEGIES = (("Region growing (K, H)", "region_growing"),
              ("Coarse-to-fine multi-primitive with MPGC (Z)", "coarse_to_fine"))


class MatchPoints(PushbroomAlgorithm):
    NAME = "matchpoints"
    DISPLAY_NAME = "Match points (region growing)"
    GROUP = "Matching"
    GROUP_ID = "matching"
    HELP = ("Dense image points by region-growing least-squares matching (Otto & Chau) in the combinations "
            "of Kornus et al. 2006, section 3.3: (a) reference-forward, (b) reference-backward with the "
            "reference points of (a) as transfer points, (c) backward-forward with the backward points of "
            "(b) as transfer points. Points are grouped: 1 two-ray, 2 three-ray from two combinations, 3 "
            "three-ray from all three (the doubly matched forward coordinates averaged and kept where their "
            "deviation is below 3 robust sigma), then, by default, refined by multi-photo geometrically "
            "constrained matching (MPGC) in both search images at once, on the sensor models corrected by an "
            "affine image bias fitted to the points' rays; with 'support weights' (advanced, off by default, "
            "on in the pipeline model) MPGC's window is weighted towards the template centre and the samples "
            "of its brightness, so a point near forest or buildings takes less of their height into "
            "the field's. A two-image block gives group 1 only. The points are "
            "stored beside the block (<block>.mass_points.npz), shown as a point layer on the reference "
            "image at the mean height, and counted per group like Table 1 of the paper (log and CSV). Seeds "
            "are automatic (interest points matched along the path the sensor models predict over the "
            "terrain height range), the block's tie points (re-matched from their stored positions), or "
            "both; with tie points only, tiles without one stay empty. With a second, wider template "
            "(advanced, off by default), a point whose match fails in the template is matched again in it: "
            "weak or striped texture then gets points that pass every acceptance criterion but are less "
            "accurate than their error ellipses say. Strategy 'coarse-to-fine' (Zhang & Gruen): Foerstner "
            "and grid points matched by NCC along the sensor models' epipolar paths level by "
            "level of a factor-3 pyramid, each level's TIN guiding the next, refined by multi-photo "
            "geometrically constrained matching (MPGC); its points (group 3 three-ray, 1 two-ray) carry MPGC's "
            "reliability as rho, points MPGC does not accept keep a low one (and MPGC's position where it "
            "converged, else the NCC one); the region growing parameters (seeds, template, STEP, thresholds, "
            "tile) do not apply to it, its own are the advanced 'Coarse-to-fine' ones.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        d = GrowParams()
        c = hierarchical.CoarseToFineParams()
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block", extension="gpkg"))
        self.addParameter(QgsProcessingParameterEnum("STRATEGY", "Matching strategy",
                                                     [label for label, _ in STRATEGIES], defaultValue=0))
        self.addParameter(QgsProcessingParameterString(
            "IMAGES", "Images in combination order: reference (nadir), forward[, backward]; empty = all",
            "", optional=True))
        self.addParameter(Number("MIN_HEIGHT", "Lowest ellipsoidal terrain height (m; empty: the block's terrain "
                                 "height range)", Number.Double, None, optional=True))
        self.addParameter(Number("MAX_HEIGHT", "Highest ellipsoidal terrain height (m; empty: the block's terrain "
                                 "height range)", Number.Double, None, optional=True))
        self.addParameter(QgsProcessingParameterEnum("SEEDS", "Seeds", [label for label, _, _ in SEED_SOURCES],
                                                     defaultValue=0))
        self.addParameter(Number("TEMPLATE", "Template size (px, odd)", Number.Integer, d.template, minValue=5))
        self.addParameter(Number("STEP", "STEP: distance of the neighbours (px)", Number.Integer, d.step, minValue=1))
        advanced = [
            Number("WIDE_TEMPLATE", "Second, wider template where the first one fails (px, odd; 0 = off)",
                   Number.Integer, d.wide_template, minValue=0),
            Number("RHO_MIN", "Minimum correlation coefficient", Number.Double, d.rho_min, minValue=0.0,
                   maxValue=1.0),
            Number("MAX_ELLIPSE", "Maximum semi-major axis of the error ellipse (px)", Number.Double,
                   d.max_ellipse, minValue=0.0),
            Number("MAX_SHIFT", "Maximum shift from the initial values (px)", Number.Double, d.max_shift,
                   minValue=0.0),
            Number("MAX_ITERATIONS", "Maximum LSM iterations", Number.Integer, d.max_iterations, minValue=1),
            Number("TILE", "Tile size of the reference image (px)", Number.Integer, d.tile, minValue=16),
            Number("SIGMA_FACTOR", "Group 3 consistency test: deviations below k robust sigma", Number.Double,
                   3.0, minValue=0.1),
            QgsProcessingParameterBoolean("GROW_SECOND", "Also grow combination (b) where (a) found no points",
                                          True),
            QgsProcessingParameterBoolean("MPGC_REFINE", "Refine the group 3 points by MPGC (three images)", True),
            QgsProcessingParameterBoolean("MPGC_SUPPORT", "MPGC refinement with support weights (heights of the "
                                          "template centre's surface; for DEMs)", d.support_weights),
            Number("WORKERS", "Worker threads", Number.Integer, 1, minValue=1),
            Number("COARSE_TO_FINE_GRID", "Coarse-to-fine: grid point spacing at full resolution (px)", Number.Integer, c.grid,
                   minValue=2),
            Number("COARSE_TO_FINE_RHO_MIN", "Coarse-to-fine: minimum correlation coefficient at full resolution",
                   Number.Double, c.rho_min, minValue=0.0, maxValue=1.0),
            Number("COARSE_TO_FINE_TILE", "Coarse-to-fine: tile size of the reference image (px)", Number.Integer, c.tile,
                   minValue=16),
            QgsProcessingParameterBoolean("COARSE_TO_FINE_EDGE_POINTS", "Coarse-to-fine: matched edges as extra points and "
                                          "breaklines (off: blunders on steep forest)", c.edge_points),
        ]
        self.addAdvancedParameters(advanced)
        self.addParameter(QgsProcessingParameterFileDestination(
            "SUMMARY", "Summary per point group (CSV)", "CSV files (*.csv)", optional=True))
        self.addOutput(QgsProcessingOutputVectorLayer("POINTS", "Mass points", QgsProcessing.TypeVectorPoint))
        self.addOutput(QgsProcessingOutputFile("BLOCK", "Block (updated; chains the next step in a model)"))
        self.addOutput(QgsProcessingOutputFile("POINTS_FILE", "Mass point file (.npz)"))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, "BLOCK", context)
        rows = combinations.combination_order(block.read_images(path), self.parameterAsString(parameters, "IMAGES", context))
        models = [block.load_model(path, r["id"]) for r in rows]

        heights = height_range(self.parameterAsOptionalDouble(parameters, "MIN_HEIGHT", context),
                               self.parameterAsOptionalDouble(parameters, "MAX_HEIGHT", context), block.height_range(path))
        params = GrowParams(
            template=self.parameterAsInt(parameters, "TEMPLATE", context),
            wide_template=self.parameterAsInt(parameters, "WIDE_TEMPLATE", context),
            step=self.parameterAsInt(parameters, "STEP", context),
            rho_min=self.parameterAsDouble(parameters, "RHO_MIN", context),
            max_ellipse=self.parameterAsDouble(parameters, "MAX_ELLIPSE", context),
            max_shift=self.parameterAsDouble(parameters, "MAX_SHIFT", context),
            max_iterations=self.parameterAsInt(parameters, "MAX_ITERATIONS", context),
            tile=self.parameterAsInt(parameters, "TILE", context),
            support_weights=self.parameterAsBool(parameters, "MPGC_SUPPORT", context)).check()
        _, use_tie_points, automatic = SEED_SOURCES[self.parameterAsEnum(parameters, "SEEDS", context)]
        seed_points = points.load_points(path, "tie_points") if use_tie_points else None
        feedback.pushInfo("combination order: " + ", ".join(r["name"] for r in rows)
                          + f"; height range {heights}")
        if STRATEGIES[self.parameterAsEnum(parameters, "STRATEGY", context)][1] == "coarse_to_fine":
            hier_params = hierarchical.CoarseToFineParams(
                grid=self.parameterAsInt(parameters, "COARSE_TO_FINE_GRID", context),
                rho_min=self.parameterAsDouble(parameters, "COARSE_TO_FINE_RHO_MIN", context),
                tile=self.parameterAsInt(parameters, "COARSE_TO_FINE_TILE", context),
                edge_points=self.parameterAsBool(parameters, "COARSE_TO_FINE_EDGE_POINTS", context)).check()
            result = coarse_to_fine.match_coarse_to_fine(
                [r["image_path"] for r in rows], models, names=[r["name"] for r in rows],
                image_ids=[r["id"] for r in rows], params=hier_params, height_range=heights,
                feedback=feedback)
        else:
            result = combinations.match_block(
                [r["image_path"] for r in rows], models, names=[r["name"] for r in rows],
                image_ids=[r["id"] for r in rows], params=params, height_range=heights,
                seed_points=seed_points, automatic=automatic, feedback=feedback,
                workers=self.parameterAsInt(parameters, "WORKERS", context),
                grow_second=self.parameterAsBool(parameters, "GROW_SECOND", context),
                sigma_factor=self.parameterAsDouble(parameters, "SIGMA_FACTOR", context),
                refine=self.parameterAsBool(parameters, "MPGC_REFINE", context))
        npz = points.save_points(path, result, "mass_points",
                                 display=(models[0], rows[0]["id"], mean_height(heights)))
        layer = points.layer_source(path, "mass_points")
        summary = combinations.summary_rows(result)
        feedback.pushInfo("points per group (Kornus et al. 2006, Table 1):\n" + combinations.format_summary(summary))
        out = {"BLOCK": path, "POINTS": layer, "POINTS_FILE": npz}
        csv = self.parameterAsFileOutput(parameters, "SUMMARY", context)
        if csv:
            out["SUMMARY"] = combinations.write_summary_csv(csv, summary)
        load_styled(context, layer, "Mass points", "POINTS", "points_by_group.qml")
        return out
