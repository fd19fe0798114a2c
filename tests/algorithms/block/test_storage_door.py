"""One storage door: only algorithms/block/ writes the block's GeoPackage and its point files. The test reads the
source of algorithms/, plugin/ and ui/ and names the file and line of every GeoPackage/SQLite write elsewhere."""

import ast
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCANNED = ("algorithms", "plugin", "ui")
DOOR = "algorithms/block/"
#: modules that write GeoPackages of their own (step outputs, never the block), each for the reason given
ALLOWED = {
    "algorithms/surface/pointcloud.py": "pushbroom:intersectpoints' point cloud output",
    "algorithms/adjustment/residual_vectors.py": "pushbroom:bundleadjust's residual vector layer output",
    "algorithms/surface/gap_fill.py": "pushbroom:interpolatedem's DEM (a GeoTIFF, temporary name) filled in place",
}
#: OGR calls that change a data source
WRITE_METHODS = {
    "CreateDataSource",
    "CreateLayer",
    "DeleteLayer",
    "CreateField",
    "DeleteField",
    "AlterFieldDefn",
    "CreateFeature",
    "SetFeature",
    "UpsertFeature",
    "DeleteFeature",
    "StartTransaction",
    "CommitTransaction",
    "savez",
    "savez_compressed",
    "executemany",
    "executescript",
}
WRITE_SQL = re.compile(
    r"\s*(INSERT|UPDATE|DELETE|REPLACE|CREATE|DROP|ALTER|RECOMPUTE|VACUUM|PRAGMA\s+\w+\s*=)", re.IGNORECASE
)


def _literal_prefix(node):
    """The literal text an SQL argument starts with ('' where it is not a string literal)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr) and node.values and isinstance(node.values[0], ast.Constant):
        return node.values[0].value
    return ""


def _is_update_open(call):
    """ogr.Open(path, 1), ogr.Open(path, update=True), gdal.Open(path, gdal.GA_Update), or a mode that is not a
    literal (gdal.GA_ReadOnly and a false constant are read-only)."""
    flag = call.args[1] if len(call.args) > 1 else next((k.value for k in call.keywords if k.arg == "update"), None)
    if flag is None or (isinstance(flag, ast.Attribute) and flag.attr == "GA_ReadOnly"):
        return False
    return not (isinstance(flag, ast.Constant) and not flag.value)


def storage_writes(source):
    """(line, what) of every GeoPackage/SQLite write in `source`: sqlite3, writing OGR calls, writing SQL (or SQL
    that is not a literal, which cannot be told apart), update-mode opens, np.savez."""
    hits = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "sqlite3" for a in node.names):
            hits.append((node.lineno, "import sqlite3"))
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "sqlite3":
            hits.append((node.lineno, "import sqlite3"))
        elif isinstance(node, ast.Attribute) and node.attr == "OF_UPDATE":
            hits.append((node.lineno, "gdal.OF_UPDATE"))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            name = node.func.attr
            if name in WRITE_METHODS:
                hits.append((node.lineno, name))
            elif name == "ExecuteSQL" and node.args:
                sql = _literal_prefix(node.args[0])
                if not sql or WRITE_SQL.match(sql):
                    hits.append((node.lineno, f"ExecuteSQL({sql.strip()[:30] or '<not a literal>'})"))
            elif name == "Open" and _is_update_open(node):
                hits.append((node.lineno, "Open in update mode"))
    return sorted(hits)


def test_scanner_catches_writes():
    source = (
        "import sqlite3\n"
        "ds = ogr.Open(path, 1)\n"
        "ds.ExecuteSQL(f'DELETE FROM {table}')\n"
        "ds.ExecuteSQL('SELECT 1')\n"
        "layer.CreateFeature(feat)\n"
        "np.savez(f, points=p)\n"
        "gdal.OpenEx(path, gdal.OF_VECTOR | gdal.OF_UPDATE)\n"
        "ogr.Open(path, update=0)\n"
        "gdal.Open(path, gdal.GA_ReadOnly)\n"
        "gdal.Open(path, gdal.GA_Update)\n"
    )
    assert [line for line, _ in storage_writes(source)] == [1, 2, 3, 5, 6, 7, 10]


def test_only_the_block_package_writes_the_block():
    assert all((ROOT / path).is_file() for path in ALLOWED), "an allowed module is gone: shorten ALLOWED"
    offenders = []
    for folder in SCANNED:
        for path in sorted((ROOT / folder).rglob("*.py")):
            relative = path.relative_to(ROOT).as_posix()
            if relative.startswith(DOOR) or relative in ALLOWED:
                continue
            offenders += [f"{relative}:{line}: {what}" for line, what in storage_writes(path.read_text("utf-8"))]
    # a write outside algorithms/block/ bypasses its transactions, generations and versioned point folders:
    # go through block.Block instead (or, for a step's own output file, add it to ALLOWED with the reason)
    assert not offenders, "writes outside algorithms/block/:\n" + "\n".join(offenders)
