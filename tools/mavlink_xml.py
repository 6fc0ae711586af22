"""Fetch MAVLink's common/standard/minimal.xml from the pymavlink sdist and check (or copy) them.

    python tools/mavlink_xml.py            # download, compare with hil/message_definitions/
    python tools/mavlink_xml.py --copy     # ... and overwrite the pinned copies

Uses only pip (`pip download --no-deps --no-binary pymavlink pymavlink==VERSION`): the sdist
holds `message_definitions/v1.0/*.xml`. Prints each file's sha256; exits 1 if a pinned copy
differs from the package's (without --copy).
"""

from __future__ import annotations

import argparse
import hashlib
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEST = ROOT / "hil" / "message_definitions"
FILES = ("common.xml", "standard.xml", "minimal.xml")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--version", default="2.4.50", help="pymavlink version (default 2.4.50)")
    ap.add_argument("--copy", action="store_true", help="overwrite the pinned copies")
    args = ap.parse_args(argv)

    status = 0
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--no-deps",
                        "--no-binary", "pymavlink", f"pymavlink=={args.version}", "-d", tmp],
                       check=True)
        sdist = Path(tmp) / f"pymavlink-{args.version}.tar.gz"
        print(f"{hashlib.sha256(sdist.read_bytes()).hexdigest()}  {sdist.name}")
        with tarfile.open(sdist) as tar:
            for name in FILES:
                member = f"pymavlink-{args.version}/message_definitions/v1.0/{name}"
                data = tar.extractfile(member).read()
                digest = hashlib.sha256(data).hexdigest()
                dest = DEST / name
                same = dest.is_file() and dest.read_bytes() == data
                print(f"{digest}  {member}  {'same as pinned' if same else 'DIFFERS from pinned'}")
                if args.copy:
                    dest.write_bytes(data)
                elif not same:
                    status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
