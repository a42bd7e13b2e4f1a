"""The dataset's Parquet files, written with pyarrow (the ``export`` extra): the frames, the
episodes and the tasks, typed as LeRobot writes them."""

from __future__ import annotations

import json
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

import numpy as np

from actionreasoning.errors import ConfigError

try:
    import pyarrow as pa  # type: ignore[import-untyped]
    import pyarrow.parquet as pq  # type: ignore[import-untyped]
except ImportError as error:
    raise ConfigError(
        "export lerobot needs pyarrow: pip install 'actionreasoning[export]'"
    ) from error

#: tasks.parquet's index column, which pandas (and so LeRobot) reads back as the index.
TASK = "task"


def write_frames(path: Path, columns: Mapping[str, np.ndarray]) -> None:
    """The frames' table: a column per feature, a vector feature's of fixed-size lists
    (LeRobot's ``Sequence(length=n)``)."""
    arrays = {}
    for name, values in columns.items():
        if values.ndim == 2:
            flat = pa.array(values.ravel())
            arrays[name] = pa.FixedSizeListArray.from_arrays(flat, values.shape[1])
        else:
            arrays[name] = pa.array(values)
    _write(path, pa.table(arrays))


def write_episodes(
    path: Path, columns: Mapping[str, Sequence[object]], texts: Collection[str] = ()
) -> None:
    """The episodes' table, each column's type taken from its values but those named in
    ``texts``: strings, where None is null."""
    arrays = {
        name: pa.array(values, type=pa.string() if name in texts else None)
        for name, values in columns.items()
    }
    _write(path, pa.table(arrays))


def write_tasks(path: Path, tasks: Sequence[str]) -> None:
    """``tasks.parquet``: each task's text and index, the text being the index pandas reads
    back (LeRobot looks tasks up by it), as pandas' own metadata says."""
    pandas = {
        "index_columns": [TASK],
        "column_indexes": [],
        "columns": [
            {"name": TASK, "field_name": TASK, "pandas_type": "unicode", "numpy_type": "object",
             "metadata": None},
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": None},
        ],
    }  # fmt: skip
    table = pa.table(
        {TASK: pa.array(tasks, pa.string()), "task_index": pa.array(range(len(tasks)), pa.int64())}
    )
    _write(path, table.replace_schema_metadata({"pandas": json.dumps(pandas)}))


def _write(path: Path, table: pa.Table) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(table, path, compression="snappy")
