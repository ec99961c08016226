"""Pack the training runs under a folder into one archive (the GPU scripts' results come back as
few files): OUT/policies.zip holds every file of the runs named, which are then removed.

    python3 benchmarks/pack_runs.py OUT RUN [RUN ...]
"""

from __future__ import annotations

import pathlib
import shutil
import sys
import zipfile


def pack(out: pathlib.Path, runs: list[str]) -> None:
    """Write `out`/policies.zip with the files of `out`/RUN for each of `runs`, then remove those folders."""
    with zipfile.ZipFile(out / "policies.zip", "w") as archive:
        for run in runs:
            for path in sorted((out / run).glob("**/*")):
                if path.is_file():
                    archive.write(path, path.relative_to(out))
    for run in runs:
        shutil.rmtree(out / run, ignore_errors=True)


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    pack(pathlib.Path(sys.argv[1]), sys.argv[2:])
