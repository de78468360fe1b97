"""Make the default product sets and list every file's SHA-256, or compare two listings.

Used to show that a refactoring leaves every product byte-identical (issue 20):

    python tools/product_hashes.py make REV OUT.sha     # `fluxcal demo` of commit REV
    python tools/product_hashes.py compare BEFORE.sha AFTER.sha

``make`` checks commit ``REV`` out at a fixed path (`SOURCE`), runs its ``fluxcal
demo`` (every mission's `make demo` runs: MESSENGER ``edr2cdr`` and ``batch``, Rosetta
``calibrate``, ``clean`` and ``batch``, the fits and the archive round trip) into a fixed
folder (`WORK`) with ``SOURCE_DATE_EPOCH`` fixed, so that the provenance (times, input
and calibration paths) is the same for both commits, and writes one line
``<sha256>  <path relative to the demo folder>`` per file.  ``compare`` prints every
path that differs, is missing or is new, and exits 1 when any does.  Files that cannot
be byte-identical by construction (batch reports and manifests, with wall-clock seconds)
are listed under ``VOLATILE``.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

#: Where each commit is checked out and where its demo writes (the same for every commit).
SOURCE = Path(tempfile.gettempdir()) / "fluxcal-product-hashes" / "src"
WORK = Path(tempfile.gettempdir()) / "fluxcal-product-hashes" / "demo"
#: Name patterns whose content holds wall-clock times or process ids by design.
VOLATILE = ("batch_report_", "manifests/", ".fluxcal-batch.lock")


def listing(folder: Path) -> dict[str, str]:
    """Map each file under ``folder`` (relative path) to its SHA-256."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def make(rev: str, target: Path) -> None:
    """Run the demo of commit ``rev`` (fixed paths, SOURCE_DATE_EPOCH) and list its files."""
    repo = Path(__file__).resolve().parents[1]
    for path in (SOURCE, WORK):
        if path.exists():
            subprocess.run(["git", "-C", str(repo), "worktree", "remove", "--force", str(path)],
                           capture_output=True)
            shutil.rmtree(path, ignore_errors=True)
    subprocess.run(["git", "-C", str(repo), "worktree", "add", "--detach", str(SOURCE), rev],
                   check=True)
    env = dict(os.environ, SOURCE_DATE_EPOCH="1700000000", PYTHONPATH=str(SOURCE / "src"))
    try:
        subprocess.run([sys.executable, "-m", "fluxcal.cli", "demo", "--out", str(WORK)],
                       check=True, env=env, cwd=SOURCE)
    finally:
        subprocess.run(["git", "-C", str(repo), "worktree", "remove", "--force", str(SOURCE)],
                       check=False)
    lines = [f"{h}  {p}" for p, h in listing(WORK).items()]
    target.write_text("\n".join(lines) + "\n")
    kept = target.with_suffix(".demo")
    shutil.rmtree(kept, ignore_errors=True)
    shutil.move(str(WORK), kept)  # for `compare --products`
    print(f"{len(lines)} files of {rev} listed in {target} (products in {kept})")


def compare(before: Path, after: Path) -> int:
    """Print the paths that differ between two listings; return 1 if any (volatile aside)."""
    def read(p: Path) -> dict[str, str]:
        rows = (line.split("  ", 1) for line in p.read_text().splitlines() if line)
        return {path: digest for digest, path in rows}

    a, b = read(before), read(after)
    bad = 0
    for path in sorted(set(a) | set(b)):
        volatile = any(v in path for v in VOLATILE)
        if path not in b:
            status = "missing"
        elif path not in a:
            status = "new"
        elif a[path] != b[path]:
            status = "differs"
        else:
            continue
        print(f"{status:8s} {'(volatile) ' if volatile else ''}{path}")
        bad += not volatile
    same = sum(1 for p in set(a) & set(b) if a[p] == b[p])
    print(f"{same} identical, {bad} non-volatile differences")
    return 1 if bad else 0


def main() -> int:
    """Command line (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    m = sub.add_parser("make")
    m.add_argument("rev")
    m.add_argument("target", type=Path)
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = parser.parse_args()
    if args.command == "make":
        make(args.rev, args.target)
        return 0
    return compare(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main())
