"""The block: one GeoPackage per block and the point files beside it, read and written only through `Block`.

The submodules hold the implementation by concern: schema.py (tables, opening, transactions, generation
counters, block_info), images.py (creation, images table, sensor models), points.py (mass and tie points:
versioned point folders of point parts and their display layers), control_points.py (control/check points and image
measurements), measurements.py (single edits of those, for the measurement window), residuals.py (the
last adjustment's residuals) and replacement.py (a new result far fewer than the stored one is refused).
Code outside this package goes through `Block`."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from osgeo import ogr

from ..adjustment.observations import Observations
from ..matching.points import MultiPoints
from ..progress import Feedback
from ..sensors.base import SensorModel
from . import control_points, images, measurements, points, residuals, schema
from .images import ImageEntry
from .points import Display, Fill

if TYPE_CHECKING:
    from ..dem_store import StoredDem


class Transaction:
    """Writes inside one `Block.transaction`: all are committed together when the `with` block ends, or none."""

    def __init__(self, ds: ogr.DataSource) -> None:
        self._ds = ds

    def write_models(
        self, models: Mapping[int, SensorModel], step: str = "adjust", message: str = "", supplied: bool = False
    ) -> None:
        """Replace the sensor models {image_id: model} (with `supplied`, the supplied models too) and log
        the step; bumps the models' generation."""
        images.write_models(self._ds, models, step, message, supplied)

    def write_residuals(self, meas_rows: Sequence[Sequence[Any]], point_rows: Sequence[Sequence[Any]]) -> None:
        """Replace the residual tables and the control points' residual_px (adjustment/residual_rows.py's
        residual_rows)."""
        residuals.write_residuals(self._ds, meas_rows, point_rows)

    def write_info(self, values: Mapping[str, object], step: str | None = None, message: str = "") -> None:
        """Set block_info keys (a dict) and, with `step`, append a run_log row."""
        schema.write_info(self._ds, values, step, message)


class Block:
    """The block GeoPackage `path` (.gpkg) and its point files. Every method opens the block anew (no
    connection is kept); each write is one SQLite transaction (schema.py).

    One identity: `path` is the block's real path (schema.real_path), whatever symbolic link the user
    gave, so its point folders live beside the real file and every step sees the same points through a
    link and through the real path. A step reports the path the user gave back as its BLOCK output."""

    #: the ways to store control points: replace the stored ones, or merge into them (control_points.py)
    IMPORT_MODES = control_points.MODES
    #: the layer of the control/check points
    CONTROL_LAYER = control_points.LAYER

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = schema.real_path(path)

    def __repr__(self) -> str:
        return f"Block({self.path!r})"

    # -- creation ---------------------------------------------------------------------------------

    @staticmethod
    def open_images(
        image_paths: Iterable[str | os.PathLike[str]], orientation_paths: Iterable[str | os.PathLike[str]] | None = None
    ) -> list[ImageEntry]:
        """(name, image path, orientation path, model) per image, the input of `create` (images.py)."""
        return images.open_images(image_paths, orientation_paths)

    @classmethod
    def create(
        cls,
        path: str | os.PathLike[str],
        image_list: Sequence[ImageEntry],
        height: float | None = 0.0,
        dem: StoredDem | None = None,
        overwrite: bool = False,
        feedback: Feedback | None = None,
        height_range: tuple[float, float] | None = None,
    ) -> Block:
        """Create the block `path` from `image_list` (`open_images`), footprints on `dem` or at `height` (None
        with a `dem`), with the terrain `height_range` where known; refuses to replace an existing block unless
        `overwrite` (images.create_block). Returns the Block."""
        return cls(
            images.create_block(schema.real_path(path), image_list, height, dem, overwrite, feedback, height_range)
        )

    # -- block information, generations, transactions ---------------------------------------------

    def info(self) -> dict[str, str]:
        """The block_info table as a dict."""
        return schema.read_info(self.path)

    def update_info(self, values: Mapping[str, object], step: str | None = None, message: str = "") -> None:
        """Set block_info keys and, with `step`, append a run_log row, in one transaction."""
        schema.update_info(self.path, values, step, message)

    def run_log(self) -> list[dict[str, str]]:
        """The run_log rows (dicts: time, step, parameters, message), oldest first."""
        return schema.read_run_log(self.path)

    def height_range(self) -> tuple[float, float] | None:
        """The terrain height range (min, max) recorded at the block's creation, or None."""
        return schema.height_range(self.path)

    def generations(self) -> dict[str, int]:
        """{part: generation} of the block now (schema.py)."""
        return schema.generations(self.path)

    def check_writable(self, what: str = "the results") -> None:
        """StorageError now where the block cannot be written (locked, read-only, damaged)."""
        schema.check_writable(self.path, what)

    @contextlib.contextmanager
    def transaction(self, what: str = "the edit", expect: Mapping[str, int] | None = None) -> Iterator[Transaction]:
        """A `Transaction` holding the block's write lock; committed when the `with` block ends, rolled back
        on any error; refused (StorageError, nothing written) if a generation of `expect` changed
        (schema.transaction)."""
        with schema.transaction(self.path, what, expect) as ds:
            yield Transaction(ds)

    def files(self) -> dict[str, str]:
        """{path: what it is to the block} of every file and folder of the block and every file it refers to, by
        real path: the GeoPackage, its SQLite journals (schema.journals), its point folders (points.point_folders:
        referenced or left by a killed store) and its images' rasters and orientation files. No step writes
        over one of them (algorithms/destinations.py)."""
        referred: dict[str, str] = {}
        for row in self.images():
            for key, part in (("image_path", "the image"), ("orientation_path", "the orientation file of image")):
                if row[key]:
                    referred.setdefault(os.path.realpath(row[key]), f"{part} {row['name']}")
        return {
            self.path: "",
            **{p: "its SQLite journal" for p in schema.journals(self.path)},
            **{p: "its point folder" for p in points.point_folders(self.path)},
            **referred,
        }

    def layer_source(self, layer_name: str) -> str:
        """The OGR source string of the block's layer `layer_name`."""
        return points.layer_source(self.path, layer_name)

    # -- images and sensor models ----------------------------------------------------------------

    def images(self) -> list[dict[str, Any]]:
        """The images table as a list of dicts (id, name, image_path, orientation_path, model_kind, ...)."""
        return images.read_images(self.path)

    def image_ids(self) -> dict[str, int]:
        """{image name: image id}, in block order."""
        return images.image_ids(self.path)

    def models(self, image_ids: Iterable[int] | None = None, supplied: bool = False) -> dict[int, SensorModel]:
        """{image id: stored sensor model} of `image_ids` (default: all, in block order), read at once; with
        `supplied`, the ones the block was created with."""
        return images.load_models(self.path, image_ids, supplied)

    def model(self, image_id: int, supplied: bool = False) -> SensorModel:
        """The stored sensor model of image `image_id` (`models`)."""
        return self.models([image_id], supplied)[image_id]

    def save_models(
        self, models: Mapping[int, SensorModel], step: str = "adjust", message: str = "", supplied: bool = False
    ) -> None:
        """`Transaction.write_models` in a transaction of its own."""
        images.save_models(self.path, models, step, message, supplied)

    def footprints(self) -> list[tuple[str, str]]:
        """[(name, WKT polygon)] of the image footprints (EPSG:4326)."""
        return images.read_footprints(self.path)

    # -- multi-image points ----------------------------------------------------------------------

    def points(self, kind: str = "mass_points") -> MultiPoints:
        """The MultiPoints of `kind` (points.KINDS) stored with the block."""
        return points.load_points(self.path, kind)

    def point_parts(self, kind: str = "mass_points") -> list[str]:
        """The part files of the points of `kind` stored with the block, to be read one at a time
        (points.load_arrays); points.py has the layout."""
        return points.point_parts(points.point_folder(self.path, kind), points.MAKERS.get(kind, "the step"))

    def store_points(
        self,
        multi: MultiPoints,
        kind: str = "mass_points",
        display: Display | None = None,
        feedback: Feedback | None = None,
        replace_fewer: bool = False,
    ) -> str:
        """Store `multi` (MultiPoints) as the block's points of `kind` and, given `display` = (sensor model,
        image id, mean height), as its point layer `kind`; far fewer than the stored ones only with
        `replace_fewer` (replacement.py). Returns the point folder path (points.store_points)."""
        return points.store_points(self.path, multi, kind, display, feedback, replace_fewer)

    def point_stats(self, kind: str = "mass_points") -> dict[str, Any]:
        """The run-level stats of the points of `kind` stored with the block (without reading the points)."""
        return points.read_stats(points.point_folder(self.path, kind), points.MAKERS.get(kind, "the step"))

    def store_point_parts(
        self,
        kind: str,
        fill: Fill,
        display: Display | None = None,
        feedback: Feedback | None = None,
        replace_fewer: bool = False,
    ) -> str:
        """Store the points that `fill(folder)` writes as parts into the new point folder (points.store_point_parts:
        a tiled step's tasks; far fewer than the stored ones only with `replace_fewer`); returns the point folder
        path."""
        return points.store_point_parts(self.path, kind, fill, display, feedback, replace_fewer)

    def write_point_layer(
        self,
        layer_name: str,
        multi: MultiPoints,
        model: SensorModel,
        image_id: int,
        height: float,
        feedback: Feedback | None = None,
    ) -> str:
        """(Re)write the display layer `layer_name` of `multi`; returns its source (points.write_point_layer)."""
        return points.write_point_layer(self.path, layer_name, multi, model, image_id, height, feedback)

    # -- control points, measurements, residuals -------------------------------------------------

    def control_points(self) -> Observations:
        """The stored control/check points and their image measurements (Observations; empty before any)."""
        return control_points.load_control_points(self.path)

    def save_control_points(
        self,
        observations: Observations,
        mode: str = "replace",
        feedback: Feedback | None = None,
        names: Mapping[str, int] | None = None,
        replace_fewer: bool = False,
    ) -> Observations:
        """Store control/check points, replacing or merging into the stored ones (IMPORT_MODES), in one
        transaction; far fewer points or measurements than the stored ones only with `replace_fewer`
        (replacement.py). Returns what is stored (control_points.save_control_points)."""
        return control_points.save_control_points(self.path, observations, mode, feedback, names, replace_fewer)

    def create_control_points(self) -> None:
        """Create the (empty) control points layer and measurement table where missing."""
        with schema.transaction(self.path, "the control points layer") as ds:
            control_points.layers(ds)

    def measurement_store(self) -> measurements.MeasurementStore:
        """A MeasurementStore: single, undoable edits of points and measurements (measurements.py)."""
        return measurements.MeasurementStore(self.path)

    def save_residuals(self, meas_rows: Sequence[Sequence[Any]], point_rows: Sequence[Sequence[Any]]) -> None:
        """`Transaction.write_residuals` in a transaction of its own."""
        with self.transaction("the residuals") as tx:
            tx.write_residuals(meas_rows, point_rows)

    def residuals(self) -> tuple[dict[tuple[str, int], tuple[float, ...]], dict[str, tuple[float, ...]]]:
        """({(point, image id): (vx, vy, wx, wy)}, {point: (dE, dN, dH, image_rms_px)}) of the last
        adjustment for the points the block holds now; empty before any (residuals.load_residuals)."""
        return residuals.load_residuals(self.path)
