"""Build resources/models/pushbroom_pipeline.model3, the whole chain as one graphical-modeler model.

The .model3 file is the product (QGIS loads it in the graphical modeler, `qgis_process run <path>`
runs it); this script is how it is made: edit here, then run

    QT_QPA_PLATFORM=offscreen .venv/bin/python scripts/build_pipeline_model.py

Model "Pushbroom pipeline" in group "Pushbroom": id `model:Pushbroom pipeline` once it is in a models
folder (e.g. <profile>/processing/models; checked with `qgis_process list`); by path, without that:
`qgis_process run resources/models/pushbroom_pipeline.model3 -- IMAGES=... createblock:block=...`
(scripts/demo.sh). QT_HASH_SEED is set to 0 before Qt starts, so the XML attributes come out in the
same order on every build (Qt otherwise seeds its hashes at random and the file's diff is noise).
Steps, each a pushbroom algorithm, chained through their BLOCK outputs (which also orders them):
createblock -> importpoints -> (checkimage) -> matchpoints (MPGC_SUPPORT on: the heights of the template
centres' surface, for the DEM) -> selecttiepoints -> bundleadjust -> intersectpoints (mass points) -> interpolatedem ->
orthorectify (IMAGE_NAME, adjusted model, produced DEM) and assessaccuracy (point cloud and DEM against
REFERENCE, per class of CLASS_RASTER).

Cheap inputs are checked before the long steps. QGIS 3.22 checks a model's inputs up front only by their
types (checkParameterValues of the model: a number within its range, a file name with its extension; not
whether the file exists, nor what it holds), and runs a child when its inputs are ready. So the control
points are imported right after the block is made, before the matching (a POINTS file that cannot be
imported fails in seconds), and `checkimage`, an orthoimage of IMAGE_NAME onto REFERENCE at CHECK_CELL m
(seconds; the reference must cover the scene for the assessment anyway), runs before the matching too
(DEPENDS), so that a name not in the block fails then, not after the whole chain.

Inputs: IMAGES, APPROX_DEM (optional; footprints and the matching height range, else HEIGHT, else found),
HEIGHT, OVERWRITE, POINTS (control/check point CSV), CHECK_IDS, MEAS_SUFFIX, REFERENCE (DEM for the
tie point heights of the adjustment and the accuracy assessment), CLASS_RASTER (optional), STEP,
CELL, MAX_EDGE (optional; default: 3 cells or 2.5 point spacings, whichever is larger),
IMAGE_NAME, THREADS (the workers of every tiled step), EXECUTION and DASK_ADDRESS (where their tiles
run: threads, local processes or Dask, as on each step). Outputs (QGIS 3.22 names a model output
`<child id>:<output name>`): createblock:block, matchpoints:groups (CSV), bundleadjust:report,
bundleadjust:residuals, intersectpoints:pointcloud, interpolatedem:dem, orthorectify:orthoimage,
assessaccuracy:report, assessaccuracy:table (CSV), assessaccuracy:dh; outputs not given go to
temporary files (optional ones are skipped).

The dense variant, resources/models/pushbroom_pipeline_dense.model3 ("Pushbroom pipeline (dense)"), is the same
chain with semi-global matching refined by LSM (matchpoints STRATEGY 2, a point every pixel) and the per-cell
DEM of the refined points (interpolatedem METHOD 1, FALLBACK off, an empty cell the refined points of the cells
around it (RADIUS 1, the default), the gaps within FILL 10 cells filled and flagged in the mask raster beside the
DEM: studies/dense_fusion.py, docs/validation.md#dense-peers); its STEP and MAX_EDGE inputs do not apply and are
left out. Its DEM is a DSM: its orthoimage is a true orthoimage, with the occlusion mask as the output
orthorectify:occlusions, and `extractdtm` (CNES Bulldozer) makes its DTM and height above ground (extractdtm:dtm,
extractdtm:dhm). extractdtm needs CNES Bulldozer (make setup installs it; docs/steps/extractdtm.md): it runs last
(DEPENDS), so that a QGIS without Bulldozer has every other output written before the step says what to install.
The co-registration to the reference is assessaccuracy's own (COREGISTER, on by default), and a merge of several
DSMs (mergedems) has no place in a chain of one block.
"""

import os
import pathlib
import sys

os.environ["QT_HASH_SEED"] = "0"  # before Qt starts: a reproducible XML attribute order (docstring)

from qgis.core import (
    QgsApplication,
    QgsExpression,
    QgsProcessing,
    QgsProcessingModelAlgorithm,
    QgsProcessingModelChildAlgorithm,
    QgsProcessingModelChildDependency,
    QgsProcessingModelChildParameterSource,
    QgsProcessingModelOutput,
    QgsProcessingModelParameter,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
)
from qgis.PyQt.QtCore import QPointF

from pushbroom.algorithms.task_runtime import BACKENDS
from pushbroom.plugin.algorithms.base import EXECUTION_LABELS, state_range

REPO = pathlib.Path(__file__).resolve().parents[1]
MODEL = REPO / "resources" / "models" / "pushbroom_pipeline.model3"
DENSE_MODEL = REPO / "resources" / "models" / "pushbroom_pipeline_dense.model3"
Number = QgsProcessingParameterNumber

#: model inputs: (parameter, position in the modeler)
INPUTS = [
    QgsProcessingParameterMultipleLayers(
        "IMAGES", "Images (with their orientation beside them)", QgsProcessing.TypeRaster
    ),
    QgsProcessingParameterRasterLayer(
        "APPROX_DEM", "Approximate DEM (footprints, matching height range; ellipsoidal heights)", optional=True
    ),
    Number(
        "HEIGHT",
        "Mean ellipsoidal terrain height when no approximate DEM is given (m; empty: found by matching the images)",
        Number.Double,
        None,
        optional=True,
    ),
    QgsProcessingParameterBoolean("OVERWRITE", "Overwrite an existing block", False),
    QgsProcessingParameterFile(
        "POINTS", "Control and check points (CSV)", fileFilter="CSV files (*.csv *.txt);;All files (*.*)"
    ),
    QgsProcessingParameterString("CHECK_IDS", "Check point ids (comma-separated)", "", optional=True),
    QgsProcessingParameterString(
        "MEAS_SUFFIX", "Measurement column suffix ('_meas' for the simulator's points.csv)", "", optional=True
    ),
    QgsProcessingParameterRasterLayer(
        "REFERENCE", "Reference DEM (tie point heights, accuracy assessment; ellipsoidal heights)"
    ),
    QgsProcessingParameterRasterLayer("CLASS_RASTER", "Class raster for the assessment", optional=True),
    Number("STEP", "Matching: distance of the region-growing neighbours (px)", Number.Integer, 5, minValue=1),
    Number("CELL", "DEM cell size (m)", Number.Double, 10.0, minValue=1e-6),
    Number(
        "MAX_EDGE",
        "DEM: maximum triangle edge (m; empty: 3 cells or 2.5 point spacings); longer triangles are gaps",
        Number.Double,
        None,
        optional=True,
        minValue=0.0,
    ),
    QgsProcessingParameterString("IMAGE_NAME", "Image to orthorectify (name in the block)", "HRG"),
    Number(
        "THREADS",
        "Workers of the tiled steps (height search, matching, intersection, DEM, orthoimage; in the dense model the "
        "DTM's Bulldozer processes too, each holding a window of about 4080 x 4096 cells): threads, processes or "
        "local Dask workers",
        Number.Integer,
        1,
        minValue=1,
    ),
    QgsProcessingParameterEnum(
        "EXECUTION", "Execution of the tiled steps", [EXECUTION_LABELS[b] for b in BACKENDS], defaultValue=0
    ),
    QgsProcessingParameterString(
        "DASK_ADDRESS",
        "Dask scheduler address of the tiled steps (tcp://host:8786; empty: a local cluster)",
        "",
        optional=True,
    ),
]
TILED = {
    "EXECUTION": ("model", "EXECUTION"),
    "DASK_ADDRESS": ("model", "DASK_ADDRESS"),
    "WORKERS": ("model", "THREADS"),
}

#: child steps: (child id, algorithm id, {parameter: source}, {model output name: (description, child output)}),
#: a source is ("model", name), ("child", child id, output) or ("static", value)
#: cell (m) of the orthoimage that checks IMAGE_NAME before the matching (docstring): a few hundred cells a side
CHECK_CELL = 100.0
STEPS = [
    (
        "createblock",
        "pushbroom:createblock",
        {
            "IMAGES": ("model", "IMAGES"),
            "DEM": ("model", "APPROX_DEM"),
            "HEIGHT": ("model", "HEIGHT"),
            "OVERWRITE": ("model", "OVERWRITE"),
            **TILED,
        },
        {"block": ("Block", "OUTPUT")},
    ),
    (
        "importpoints",
        "pushbroom:importpoints",
        {
            "BLOCK": ("child", "createblock", "OUTPUT"),
            "INPUT": ("model", "POINTS"),
            "CHECK_IDS": ("model", "CHECK_IDS"),
            "MEAS_SUFFIX": ("model", "MEAS_SUFFIX"),
        },
        {},
    ),
    (
        "checkimage",
        "pushbroom:orthorectify",
        {
            "BLOCK": ("child", "importpoints", "BLOCK"),
            "IMAGE_NAME": ("model", "IMAGE_NAME"),
            "DEM": ("model", "REFERENCE"),
            "CELL_SIZE": ("static", CHECK_CELL),
        },
        {},
    ),
    (
        "matchpoints",
        "pushbroom:matchpoints",
        {
            "BLOCK": ("child", "importpoints", "BLOCK"),
            **TILED,
            "STEP": ("model", "STEP"),
            "MPGC_SUPPORT": ("static", True),
        },
        {"groups": ("Mass points per group (CSV)", "SUMMARY")},
    ),
    ("selecttiepoints", "pushbroom:selecttiepoints", {"BLOCK": ("child", "matchpoints", "BLOCK")}, {}),
    (
        "bundleadjust",
        "pushbroom:bundleadjust",
        {
            "BLOCK": ("child", "selecttiepoints", "BLOCK"),
            "FREE": ("static", "auto"),
            "REFERENCE_DEM": ("model", "REFERENCE"),
        },
        {
            "report": ("Adjustment report", "REPORT"),
            "residuals": ("Residual vectors of the control and check points", "RESIDUALS"),
        },
    ),
    (
        "intersectpoints",
        "pushbroom:intersectpoints",
        {"BLOCK": ("child", "bundleadjust", "BLOCK"), "POINTS": ("static", 0), **TILED},
        {"pointcloud": ("Point cloud", "OUTPUT")},
    ),
    (
        "interpolatedem",
        "pushbroom:interpolatedem",
        {
            "INPUT": ("child", "intersectpoints", "OUTPUT"),
            "CELL": ("model", "CELL"),
            "MAX_EDGE": ("model", "MAX_EDGE"),
            **TILED,
        },
        {"dem": ("DEM", "OUTPUT")},
    ),
    (
        "orthorectify",
        "pushbroom:orthorectify",
        {
            "BLOCK": ("child", "bundleadjust", "BLOCK"),
            "IMAGE_NAME": ("model", "IMAGE_NAME"),
            "DEM": ("child", "interpolatedem", "OUTPUT"),
            **TILED,
        },
        {"orthoimage": ("Orthoimage", "OUTPUT")},
    ),
    (
        "assessaccuracy",
        "pushbroom:assessaccuracy",
        {
            "REFERENCE": ("model", "REFERENCE"),
            "POINTS": ("child", "intersectpoints", "OUTPUT"),
            "DEM": ("child", "interpolatedem", "OUTPUT"),
            "CLASS_RASTER": ("model", "CLASS_RASTER"),
        },
        {
            "report": ("Accuracy report", "REPORT"),
            "table": ("Accuracy statistics (CSV)", "TABLE"),
            "dh": ("dh raster of the DEM", "DH"),
        },
    ),
]


#: children that wait for others they take no input from: {child id: [child ids]} (docstring)
DEPENDS = {"matchpoints": ["checkimage"], "extractdtm": ["orthorectify", "assessaccuracy"]}
#: children described otherwise than by their algorithm's name (QGIS names them in its messages)
DESCRIPTIONS = {"checkimage": "Check the image to orthorectify (IMAGE_NAME): a coarse orthoimage on REFERENCE"}


def source(spec, child_default=None):
    """The child parameter source of `spec`. QGIS 3.22 hands an unset model input to the child as
    unset (the child's own default applies, not the model input's): where the two defaults differ,
    the source is the expression coalesce(@input, model default)."""
    kind, *args = spec
    if kind == "model":
        default = next(p.defaultValue() for p in INPUTS if p.name() == args[0])
        if default is not None and default != child_default:
            return QgsProcessingModelChildParameterSource.fromExpression(
                f"coalesce(@{args[0]}, {QgsExpression.quotedValue(default)})"
            )
        return QgsProcessingModelChildParameterSource.fromModelParameter(args[0])
    if kind == "child":
        return QgsProcessingModelChildParameterSource.fromChildOutput(*args)
    return QgsProcessingModelChildParameterSource.fromStaticValue(args[0])


#: the dense variant's changes: {child id: {parameter: source}}, and the model inputs it leaves out
DENSE = {
    "matchpoints": {"STRATEGY": ("static", 2), "STEP": None, "MPGC_SUPPORT": None},
    "interpolatedem": {
        "METHOD": ("static", 1),
        "FALLBACK": ("static", False),
        "FILL": ("static", 10.0),
        "MAX_EDGE": None,
    },
}
DENSE_UNUSED = {"STEP", "MAX_EDGE"}
#: the dense variant's further outputs of its children: {child id: {model output name: (description, child output)}}
DENSE_OUTPUTS = {"orthorectify": {"occlusions": ("Occlusion mask of the true orthoimage", "OCCLUSIONS")}}
#: the dense variant's further children, after the others
DENSE_STEPS = [
    (
        "extractdtm",
        "pushbroom:extractdtm",
        {"DSM": ("child", "interpolatedem", "OUTPUT"), **TILED},
        {"dtm": ("DTM (Bulldozer)", "OUTPUT"), "dhm": ("Height above ground (DSM - DTM)", "DHM")},
    ),
]


def variant(dense):
    """(inputs, steps) of the model or of its dense variant."""
    if not dense:
        return INPUTS, STEPS
    steps = []
    for child_id, algorithm_id, sources, outputs in STEPS:
        sources = {**sources, **DENSE.get(child_id, {})}
        outputs = {**outputs, **DENSE_OUTPUTS.get(child_id, {})}
        steps.append((child_id, algorithm_id, {k: v for k, v in sources.items() if v is not None}, outputs))
    return [p for p in INPUTS if p.name() not in DENSE_UNUSED], steps + DENSE_STEPS


def build(dense=False):
    """The model, or its dense variant (needs a QgsApplication with the pushbroom provider registered, so that
    the children's algorithms and their outputs resolve)."""
    inputs, steps = variant(dense)
    model = QgsProcessingModelAlgorithm("Pushbroom pipeline (dense)" if dense else "Pushbroom pipeline", "Pushbroom")
    matching = (
        "semi-global matching on epipolar tiles refined by least squares, a point every pixel"
        if dense
        else "region-growing matching"
    )
    dem = "DEM (per-cell medians of the refined points)" if dense else "DEM (TIN, gaps at long triangles)"
    ortho = "a true orthoimage of one image on the adjusted model and the produced DSM, with its occlusion mask"
    ortho = ortho if dense else "orthoimage of one image on the adjusted model and the produced DEM"
    dtm = ", and last the DTM and the height above ground of the DSM (CNES Bulldozer, to be installed)" if dense else ""
    model.setHelpContent(
        {
            "ALG_DESC": (
                "The whole Pushbroom chain: block from the images and their orientation, control/check point import, "
                f"{matching}, tie point selection, bundle adjustment (automatic parameter selection), "
                f"intersection of the mass points, {dem}, {ortho}, and accuracy assessment of the point cloud and the "
                f"DEM against a reference (co-registered to it){dtm}."
            ),
            "ALG_CREATOR": "Pushbroom (scripts/build_pipeline_model.py)",
        }
    )
    for k, parameter in enumerate(inputs):
        component = QgsProcessingModelParameter(parameter.name())
        component.setPosition(QPointF(120, 60 + 70 * k))
        parameter = state_range(parameter.clone())  # the model owns it: one copy per model
        model.addModelParameter(parameter, component)
    for k, (child_id, algorithm_id, sources, outputs) in enumerate(steps):
        child = QgsProcessingModelChildAlgorithm(algorithm_id)
        child.setChildId(child_id)
        algorithm = QgsApplication.processingRegistry().algorithmById(algorithm_id)
        child.setDescription(DESCRIPTIONS.get(child_id, algorithm.displayName()))
        child.setPosition(QPointF(520, 60 + 100 * k))
        for parameter in algorithm.parameterDefinitions():  # the rest at their defaults, as the modeler does
            name = parameter.name()
            if name in sources:
                child.addParameterSources(name, [source(sources[name], parameter.defaultValue())])
            elif not parameter.isDestination() and parameter.defaultValue() is not None:
                child.addParameterSources(name, [source(("static", parameter.defaultValue()))])
        model_outputs = {}
        for name, (description, child_output) in outputs.items():
            output = QgsProcessingModelOutput(name, description)
            output.setChildId(child_id)
            output.setChildOutputName(child_output)
            output.setPosition(QPointF(900, 60 + 100 * k + 30 * len(model_outputs)))
            model_outputs[name] = output
        child.setModelOutputs(model_outputs)
        child.setDependencies([QgsProcessingModelChildDependency(c) for c in DEPENDS.get(child_id, [])])
        model.addChildAlgorithm(child)
    return model


def main():
    import pushbroom
    from pushbroom.algorithms.atomic import atomic_path

    app = QgsApplication([], False)
    app.initQgis()
    plugin = pushbroom.classFactory(None)
    plugin.initProcessing()
    for path, dense in ((MODEL, False), (DENSE_MODEL, True)):
        model = build(dense)
        ok, problems = model.validate()
        if not ok:
            sys.exit(f"model {path.name} invalid:\n" + "\n".join(problems))
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            if not model.toFile(str(tmp)):
                sys.exit(f"cannot write {path}")
        print(
            f"{path}: {len(model.childAlgorithms())} steps; inputs "
            + ", ".join(p.name() for p in variant(dense)[0])
            + "; outputs "
            + ", ".join(d.name() for d in model.destinationParameterDefinitions())
        )


if __name__ == "__main__":
    main()
