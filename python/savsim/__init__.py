"""savsim from Python: replay flight logs and run encounter sets through savsim's collision
core on every core, results as Arrow tables.

    >>> import savsim
    >>> rows = savsim.gen_encounters(100, seed=1)            # truth known by construction
    >>> table = savsim.run_manifest(rows, jobs=2)            # a pyarrow.Table, one row per run
    >>> row = savsim.replay("flight.tlog", scene="scenes/city.toml")

Columns are those of ``savsim batch`` (docs/batch.md). A run that fails (an unreadable tlog, a
bad scene) is a row whose ``error`` says why; arguments that are not a manifest raise
``SavsimError``. The GIL is released while runs run.
"""

import json
import os

import pyarrow as pa
import pyarrow.parquet as pq

from ._savsim import (
    SavsimError,
    __version__,
    gen_encounters_json as _gen_encounters_json,
    load_manifest_json as _load_manifest_json,
    run_manifest_json as _run_manifest_json,
)

__all__ = [
    "SavsimError",
    "gen_encounters",
    "load_manifest",
    "replay",
    "run_manifest",
    "__version__",
]


def load_manifest(path):
    """The rows of a manifest file (.csv, .toml or .json) as dicts, paths made relative to
    the file's directory."""
    return json.loads(_load_manifest_json(os.fspath(path)))


def gen_encounters(n, seed=1, scene=None, mode="exact", duration_s=180.0, rate_hz=10.0,
                   intruder_kind="dji"):
    """``n`` generated encounters as manifest rows (the same as ``savsim batch
    gen-encounters``); each carries its closest approach and NMAC as ``expect_*``."""
    if scene is not None:
        scene = os.path.abspath(os.fspath(scene))
    return json.loads(_gen_encounters_json(n, seed, scene, mode, duration_s, rate_hz,
                                           intruder_kind))


def run_manifest(rows, jobs=None, first_index=0):
    """Run manifest rows (a list of dicts, or a manifest file's path) on ``jobs`` threads
    (every core when None) and return the results as a ``pyarrow.Table`` in row order.
    ``first_index`` numbers the first row (for a shard of a larger manifest)."""
    if isinstance(rows, (str, os.PathLike)):
        rows = load_manifest(rows)
    data = _run_manifest_json(json.dumps(list(rows)), first_index, jobs)
    return pq.read_table(pa.BufferReader(data))


def replay(tlog, scene=None, mode="exact"):
    """Replay one tlog over a scene (open air when None); its result row as a dict. Raises
    ``SavsimError`` when the run fails."""
    row = {"tlog": os.fspath(tlog), "mode": mode}
    if scene is not None:
        row["scene"] = os.fspath(scene)
    result = run_manifest([row], jobs=1).to_pylist()[0]
    if result["error"] is not None:
        raise SavsimError(result["error"])
    return result
