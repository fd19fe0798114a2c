"""surface.ept: the Entwine Point Tiles index of a LAS/LAZ cloud. Every point of the LAS is in exactly one node,
with its coordinates and colours, inside its node's cube; the hierarchy counts the nodes' points; building it in
small buckets gives the same index as in one; and QGIS's own "ept" provider reads it (the independent reader):
its point count, CRS, attributes and RGB renderer, and a map rendered from it shows the points' colours."""

import glob
import json
import os

import numpy as np
import pytest

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.surface import ept
from pushbroom.algorithms.surface.pointcloud import laspy_module, write_point_cloud


@pytest.fixture(scope="module")
def cloud(tmp_path_factory):
    """100 000 points over 4 x 5.5 km of rolling terrain in UTM 31N, red rising east, blue north."""
    folder = tmp_path_factory.mktemp("ept")
    rng = np.random.default_rng(0)
    n = 100_000
    lon, lat = 5.2 + rng.uniform(0, 0.05, n), 44.1 + rng.uniform(0, 0.05, n)
    h = 500 + 50 * np.sin(lon * 300) + rng.normal(0, 1, n)
    fields = {
        "point_id": np.arange(n, dtype=np.int64),
        "red": ((lon - 5.2) / 0.05 * 65535).astype(np.uint16),
        "green": np.full(n, 20000, np.uint16),
        "blue": ((lat - 44.1) / 0.05 * 65535).astype(np.uint16),
    }
    path = str(folder / "cloud.laz")
    write_point_cloud(path, lon, lat, h, fields)
    return {"folder": folder, "path": path, "n": n}


def nodes(folder):
    """{(D, X, Y, Z): LasData} of an EPT folder's tiles."""
    laspy = laspy_module()
    out = {}
    for tile in glob.glob(os.path.join(folder, "ept-data", "*.laz")):
        key = tuple(int(v) for v in os.path.basename(tile)[:-4].split("-"))
        out[key] = laspy.read(tile)
    return out


def test_every_point_once_in_its_node(cloud):
    folder = str(cloud["folder"] / "whole.ept")
    result = ept.write_ept(cloud["path"], folder)
    tiles = nodes(folder)
    hierarchy = json.load(open(os.path.join(folder, "ept-hierarchy", "0-0-0-0.json")))
    metadata = json.load(open(os.path.join(folder, "ept.json")))
    assert result.points == metadata["points"] == cloud["n"] == sum(hierarchy.values())
    assert result.nodes == len(tiles) == len(hierarchy) > 1 and result.depth >= 1
    assert {f"{d}-{x}-{y}-{z}": len(t.points) for (d, x, y, z), t in tiles.items()} == hierarchy
    source = laspy_module().read(cloud["path"])
    rows = lambda las: np.column_stack([las.X, las.Y, las.Z, las.red, las.green, las.blue])
    got = np.concatenate([rows(t) for t in tiles.values()])
    assert len(got) == cloud["n"] and np.array_equal(np.unique(got, axis=0), np.unique(rows(source), axis=0))
    # a node's points lie inside its cube
    x0, y0, z0, x1, *_ = metadata["bounds"]
    side = x1 - x0
    for (d, i, j, k), t in tiles.items():
        size = side / 2**d
        for values, index, origin in ((t.x, i, x0), (t.y, j, y0), (t.z, k, z0)):
            assert np.all(values >= origin + index * size - 1e-3) and np.all(
                values <= origin + (index + 1) * size + 1e-3
            )
    for parent in tiles:  # every node's parent is a node: QGIS walks the tree from the root
        if parent[0]:
            assert (parent[0] - 1, parent[1] // 2, parent[2] // 2, parent[3] // 2) in tiles


def test_chunks_do_not_change_the_index_and_buckets_keep_every_point(cloud, monkeypatch):
    whole = str(cloud["folder"] / "one.ept")
    ept.write_ept(cloud["path"], whole)
    monkeypatch.setattr(ept, "CHUNK", 7_000)
    chunked = str(cloud["folder"] / "chunked.ept")
    ept.write_ept(cloud["path"], chunked)
    a, b = nodes(whole), nodes(chunked)
    assert set(a) == set(b) and all(np.array_equal(a[k].X, b[k].X) for k in a)  # the same points, in file order
    monkeypatch.setattr(ept, "BUCKET", 2_000)  # depth 3: 64 buckets over the surface, each built on its own
    parts = str(cloud["folder"] / "buckets.ept")
    result = ept.write_ept(cloud["path"], parts)
    got = np.concatenate([np.column_stack([t.X, t.Y, t.Z]) for t in nodes(parts).values()])
    source = laspy_module().read(cloud["path"])
    assert result.points == len(got) == cloud["n"]
    assert np.array_equal(np.unique(got, axis=0), np.unique(np.column_stack([source.X, source.Y, source.Z]), axis=0))


def test_qgis_reads_and_draws_it_in_colour(qgis_app, cloud):
    from qgis.core import QgsMapRendererSequentialJob, QgsMapSettings, QgsPointCloudLayer
    from qgis.PyQt.QtCore import QSize

    folder = str(cloud["folder"] / "qgis.ept")
    ept.write_ept(cloud["path"], folder)
    layer = QgsPointCloudLayer(os.path.join(folder, "ept.json"), "cloud", "ept")
    assert layer.isValid() and layer.pointCount() == cloud["n"] and layer.crs().authid() == "EPSG:32631"
    assert {"Red", "Green", "Blue"} <= {a.name() for a in layer.attributes().attributes()}
    assert layer.renderer().type() == "rgb"
    settings = QgsMapSettings()
    settings.setLayers([layer])
    settings.setDestinationCrs(layer.crs())
    settings.setExtent(layer.extent())
    settings.setOutputSize(QSize(200, 200))
    job = QgsMapRendererSequentialJob(settings)
    job.start()
    job.waitForFinished()
    image = job.renderedImage()
    row = [image.pixelColor(x, 100) for x in range(200)]
    drawn = [c for c in row if c.name() != "#ffffff"]
    assert len(drawn) > 100
    west, east = (np.mean([c.red() for c in part]) for part in (drawn[:10], drawn[-10:]))
    assert east > west + 150 and abs(drawn[len(drawn) // 2].green() - 20000 / 257) < 30  # drawn in their colours


def test_an_empty_cloud_is_refused(tmp_path):
    path = str(tmp_path / "empty.las")
    write_point_cloud(path, np.zeros(0), np.zeros(0), np.zeros(0), crs="EPSG:32631")
    with pytest.raises(InputError, match="holds no point"):
        ept.write_ept(path, str(tmp_path / "empty.ept"))
