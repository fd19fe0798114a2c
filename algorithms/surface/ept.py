"""A point cloud as Entwine Point Tiles (EPT 1.0.0): the octree of LAZ tiles that QGIS's "ept" provider reads. QGIS
from Debian 12 (3.22) has no PDAL provider, so it cannot open a LAS or LAZ file as a point cloud; it opens the
EPT index of one (ept.json), coloured by its Red, Green, Blue where the cloud has them.

Layout (https://entwine.io/en/latest/entwine-point-tile.html): `ept.json` (the cube `bounds`, the cloud's own
`boundsConforming`, the `schema` with X, Y, Z's scale and offset, `span`, `srs`, dataType "laszip", hierarchyType
"json"), `ept-hierarchy/0-0-0-0.json` ({"D-X-Y-Z": points} of every node) and `ept-data/D-X-Y-Z.laz` per node.

The octree. The root node is the cube around the cloud; a node of depth D is a cube of side L / 2^D, cut into
SPAN x SPAN x SPAN voxels. Each node keeps the first point (in file order) of every voxel its points occupy, and
passes the others to its eight children; a node whose points, after that, number at most LEAF keeps them all. So
each depth is a sample of the cloud at voxel size L / (2^D SPAN), which is how QGIS draws it from afar.

Memory follows the bucket, not the cloud. The cloud is read in CHUNK points and each point written to the bucket of
its node at depth B (the smallest depth whose nodes hold at most BUCKET points on average over a surface, 4^B
nodes), a file of its packed records; then each bucket is built in memory, one after the other. The voxels of the
depths above B lie inside one bucket each (SPAN >= 2^B: B <= log2(SPAN)), so every bucket fills its own share of
the coarse nodes; their points (a sample, SPAN^2 a node over a surface) are gathered over the buckets and written
last.

Every point of the LAS is in exactly one node, with its X, Y, Z integers, scale and offset unchanged, its
classification, and its Red, Green, Blue where the LAS has them (the extra bytes dimensions stay in the LAS). The
tiles are LAS 1.2, point format 3 (1 without colours; GPS time zero): QGIS 3.22's LAZ decoder stops the application
on LAS 1.4's point formats 6-8, and reads the colours at format 3's place in the record (format 2's come out
black). The schema carries each dimension's count, minimum, maximum, mean and standard deviation: QGIS reads its
colours as 16 bits (its RGB renderer stretched to 0-65535) only where the maximum says so. Written atomically: the
folder replaces any EPT folder at its path as a whole."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import progress
from ..atomic import atomic_dir, work_dir
from ..errors import InputError
from .point_input import las_srs, open_las
from .pointcloud import laspy_module

if TYPE_CHECKING:
    from ..progress import Feedback

#: voxels a node side
SPAN = 128
#: a node keeps all its remaining points where they number at most this many
LEAF = 20_000
#: points a bucket holds on average, at most
BUCKET = 4_000_000
#: points read from the LAS at a time
CHUNK = 1_000_000
#: the deepest node (its voxel indices, 2^13 SPAN a side, pack into 21 bits each: _flat)
MAX_DEPTH = 13
#: the packed record of a point in a bucket
RECORD = np.dtype(
    [
        ("X", "<i4"),
        ("Y", "<i4"),
        ("Z", "<i4"),
        ("classification", "u1"),
        ("red", "<u2"),
        ("green", "<u2"),
        ("blue", "<u2"),
    ]
)


@dataclass(frozen=True)
class EptResult:
    """What write_ept wrote: the folder, its points and its nodes."""

    folder: str
    points: int
    nodes: int
    depth: int  # the deepest node's


@dataclass(frozen=True)
class _Cube:
    """The octree's cube in the LAS's integer coordinates: its lower corner and side."""

    low: tuple[int, int, int]
    side: int

    def keys(self, records: np.ndarray, depth: int, cells: int) -> np.ndarray:
        """(n, 3) int64 cell indices of `records` on a grid of 2^depth * `cells` cells a side."""
        n = (1 << depth) * cells
        xyz = np.column_stack([records[a].astype(np.int64) - lo for a, lo in zip("XYZ", self.low)])
        return np.minimum(xyz * n // self.side, n - 1)


def _flat(keys: np.ndarray) -> np.ndarray:
    """One int64 per row of 3-D cell indices (each below 2^21)."""
    return (keys[:, 0] << 42) | (keys[:, 1] << 21) | keys[:, 2]


def _bucket_depth(points: int) -> int:
    return max(0, min(int(math.ceil(math.log(max(points, 1) / BUCKET, 4))), int(math.log2(SPAN))))


def write_ept(las_path: str, folder: str, feedback: Feedback | None = None) -> EptResult:
    """The EPT of the LAS/LAZ file `las_path` in the folder `folder` (module docstring); returns an EptResult.
    InputError for a cloud without points."""
    laspy = laspy_module()
    with open_las(las_path) as reader:
        header = reader.header
        count = int(header.point_count)
        if not count:
            raise InputError(f"the point cloud {las_path} holds no point: there is nothing to index")
        coloured = "red" in header.point_format.dimension_names
        scales, offsets = np.asarray(header.scales, float), np.asarray(header.offsets, float)
        low = np.floor((np.asarray(header.mins) - offsets) / scales).astype(np.int64)
        high = np.ceil((np.asarray(header.maxs) - offsets) / scales).astype(np.int64)
        side = int(max(high - low)) + 1
        cube = _Cube(tuple(int(v) for v in low), side)  # type: ignore[arg-type]
        wkt = las_srs(reader, las_path).ExportToWkt()
        depth_b = _bucket_depth(count)
        with work_dir(folder, "the EPT's buckets") as work, atomic_dir(folder, "the EPT folder") as out:
            os.makedirs(os.path.join(out, "ept-data"))
            os.makedirs(os.path.join(out, "ept-hierarchy"))
            stats = _Stats()
            buckets = _bucket(reader, cube, depth_b, work, coloured, stats, progress.scaled(feedback, 0, 40))
            writer = _NodeWriter(out, header, coloured, laspy)
            coarse: dict[tuple[int, ...], list[np.ndarray]] = {}
            for k, path in enumerate(buckets):
                progress.check(feedback)
                records = np.fromfile(path, RECORD)
                os.unlink(path)
                for node, part in _build(records, cube, depth_b):
                    if node[0] < depth_b:
                        coarse.setdefault(node, []).append(part)
                    else:
                        writer.write(node, part)
                progress.step(feedback, 40 + 55 * (k + 1) / len(buckets))
            for node, parts in coarse.items():
                writer.write(node, np.concatenate(parts))
            hierarchy = {f"{d}-{x}-{y}-{z}": n for (d, x, y, z), n in sorted(writer.counts.items())}
            with open(os.path.join(out, "ept-hierarchy", "0-0-0-0.json"), "w", encoding="utf-8") as f:
                json.dump(hierarchy, f)
            _write_metadata(out, header, cube, (scales, offsets), count, stats, wkt)
    progress.step(feedback, 100)
    return EptResult(str(folder), count, len(hierarchy), max(d for d, _, _, _ in writer.counts))


class _Stats:
    """Count, minimum, maximum, sum and sum of squares of each dimension, added up over the chunks."""

    def __init__(self) -> None:
        self.values: dict[str, list[float]] = {}

    def add(self, name: str, values: np.ndarray) -> None:
        v = np.asarray(values, float)
        n, lo, hi, total, squares = self.values.get(name, [0, math.inf, -math.inf, 0.0, 0.0])
        self.values[name] = [n + v.size, min(lo, v.min()), max(hi, v.max()), total + v.sum(), squares + v @ v]

    def of(self, name: str) -> dict[str, float]:
        """The schema's statistics of dimension `name`."""
        n, lo, hi, total, squares = self.values[name]
        mean = total / n
        variance = max(squares / n - mean * mean, 0.0)
        return {
            "count": int(n),
            "minimum": lo,
            "maximum": hi,
            "mean": mean,
            "stddev": math.sqrt(variance),
            "variance": variance,
        }


def _bucket(
    reader: Any, cube: _Cube, depth: int, work: str, coloured: bool, stats: _Stats, feedback: Feedback | None
) -> list[str]:
    """Write the points, packed (RECORD), to one file per node of `depth`; the files, in node order. The
    dimensions' statistics are added to `stats`."""
    paths: dict[int, str] = {}
    done = 0
    for chunk in reader.chunk_iterator(CHUNK):
        progress.check(feedback)
        records = np.zeros(len(chunk), RECORD)
        for name in ("X", "Y", "Z"):
            records[name] = np.asarray(chunk[name])
        records["classification"] = np.asarray(chunk.classification)
        if coloured:
            for name in ("red", "green", "blue"):
                records[name] = np.asarray(chunk[name])
        for name, values in (("X", chunk.x), ("Y", chunk.y), ("Z", chunk.z), ("Classification", chunk.classification)):
            stats.add(name, values)
        if coloured:
            for name in ("red", "green", "blue"):
                stats.add(name.capitalize(), records[name])
        node = _flat(cube.keys(records, depth, 1))
        order = np.argsort(node, kind="stable")
        values, starts = np.unique(node[order], return_index=True)
        for value, part in zip(values.tolist(), np.split(records[order], starts[1:])):
            path = paths.setdefault(value, os.path.join(work, f"bucket-{len(paths):06d}.bin"))
            with open(path, "ab") as f:
                part.tofile(f)
        done += len(chunk)
        progress.step(feedback, 100.0 * done / max(reader.header.point_count, 1))
    return [paths[key] for key in sorted(paths)]


def _build(records: np.ndarray, cube: _Cube, depth_b: int) -> Iterator[tuple[tuple[int, ...], np.ndarray]]:
    """Yield (node (D, X, Y, Z), its records) of one bucket's points: every depth from the root (module
    docstring), the coarse nodes' shares included."""
    remaining = records
    depth = 0
    while len(remaining) and depth <= MAX_DEPTH:
        nodes = cube.keys(remaining, depth, 1)
        flat_nodes = _flat(nodes)
        voxel = _flat(cube.keys(remaining, depth, SPAN))
        _, first = np.unique(voxel, return_index=True)
        keep = np.zeros(len(remaining), bool)
        keep[first] = True
        if depth >= depth_b:  # a node of the bucket's subtree keeps all where few would go on
            index = np.unique(flat_nodes, return_inverse=True)[1]
            keep |= (np.bincount(index, weights=~keep)[index] <= LEAF) | (depth == MAX_DEPTH)
        for part_nodes, part in _by_node(nodes[keep], flat_nodes[keep], remaining[keep]):
            yield (depth, *part_nodes), part
        remaining = remaining[~keep]
        depth += 1


def _by_node(nodes: np.ndarray, flat: np.ndarray, records: np.ndarray) -> Iterator[tuple[tuple[int, ...], np.ndarray]]:
    """(node, its records) of records whose nodes are `nodes` ((n, 3) indices; `flat`, one int64 each)."""
    order = np.argsort(flat, kind="stable")
    _, starts = np.unique(flat[order], return_index=True)
    first = nodes[order[starts]]  # each node's indices, once
    for node, part in zip(first.tolist(), np.split(records[order], starts[1:])):
        yield tuple(node), part


class _NodeWriter:
    """Writes a node's records as ept-data/D-X-Y-Z.laz (the LAS's scale and offset) and counts them."""

    def __init__(self, out: str, header: Any, coloured: bool, laspy: Any) -> None:
        self.out, self.coloured, self.laspy = out, coloured, laspy
        self.scales, self.offsets = header.scales, header.offsets
        self.counts: dict[tuple[int, ...], int] = {}

    def write(self, node: tuple[int, ...], records: np.ndarray) -> None:
        laspy = self.laspy
        header = laspy.LasHeader(point_format=3 if self.coloured else 1, version="1.2")
        header.scales, header.offsets = self.scales, self.offsets
        points = laspy.ScaleAwarePointRecord.zeros(len(records), header=header)
        for name in ("X", "Y", "Z"):
            points[name] = records[name]
        points["classification"] = records["classification"]
        if self.coloured:
            for name in ("red", "green", "blue"):
                points[name] = records[name]
        name = "-".join(str(v) for v in node)
        with laspy.open(
            os.path.join(self.out, "ept-data", f"{name}.laz"), mode="w", header=header, do_compress=True
        ) as w:
            w.write_points(points)
        self.counts[node] = self.counts.get(node, 0) + len(records)


def _write_metadata(
    out: str, header: Any, cube: _Cube, scaling: tuple[np.ndarray, np.ndarray], count: int, stats: _Stats, wkt: str
) -> None:
    scales, offsets = scaling
    low = np.asarray(cube.low, float) * scales + offsets
    bounds = [*low.tolist(), *(low + cube.side * scales).tolist()]
    schema = [
        {"name": a, "type": "signed", "size": 4, "scale": float(s), "offset": float(o), **stats.of(a)}
        for a, s, o in zip("XYZ", scales, offsets)
    ]
    schema.append({"name": "Classification", "type": "unsigned", "size": 1, **stats.of("Classification")})
    schema += [
        {"name": c, "type": "unsigned", "size": 2, **stats.of(c)} for c in ("Red", "Green", "Blue") if c in stats.values
    ]
    metadata = {
        "bounds": bounds,
        "boundsConforming": [*np.asarray(header.mins).tolist(), *np.asarray(header.maxs).tolist()],
        "dataType": "laszip",
        "hierarchyType": "json",
        "points": count,
        "schema": schema,
        "span": SPAN,
        "srs": {"wkt": wkt},
        "version": "1.0.0",
    }
    with open(os.path.join(out, "ept.json"), "w", encoding="utf-8") as f:
        json.dump(metadata, f, indent=1)
