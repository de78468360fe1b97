"""Make the default product sets and list every file's SHA-256, or compare two listings.

Used to show that a refactoring leaves every product byte-identical (issue 20):

    python tools/product_hashes.py make REV OUT.sha     # the demo tour of commit REV
    python tools/product_hashes.py compare BEFORE.sha AFTER.sha [--explain --same OLD=NEW]

``make`` checks commit ``REV`` out at a fixed path (`SOURCE`), runs its full demo tour
(``fluxcal demo --full``, or ``fluxcal demo`` for a commit from before the quick first
run, whose ``demo`` was the tour: `demo_command`; every mission's demo runs: MESSENGER
``edr2cdr`` and ``batch``, Rosetta ``calibrate``, ``clean`` and ``batch``, the fits, the
archive round trip and the runs' HTML reports) into a fixed
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


def demo_command(source: Path, env: dict[str, str]) -> list[str]:
    """Return the command running the full demo tour of the checkout at ``source``.

    ``fluxcal demo --full`` where the commit has the option (the quick first run is
    ``fluxcal demo`` since issue 25), else ``fluxcal demo``, which was the tour.
    """
    base = [sys.executable, "-m", "fluxcal.cli", "demo"]
    shown = subprocess.run([*base, "--help"], capture_output=True, text=True, env=env,
                           cwd=source)
    return [*base, "--full"] if "--full" in shown.stdout else base


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
        subprocess.run([*demo_command(SOURCE, env), "--out", str(WORK)],
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


def explain(before: Path, after: Path, same: list[str]) -> int:
    """For every file that differs between two kept demos, say what differs in it.

    ``same`` holds ``OLD=NEW`` text substitutions applied to the "before" side first
    (a moved data folder in the provenance, say).  Text files (labels, tables, reports)
    are compared line by line; CDF files variable by variable and attribute by attribute
    (cdflib); other binary files are only named.  Returns the number of files whose
    differences are not explained by the substitutions.
    """
    import cdflib  # the project's CDF reader: a dependency of fluxcal

    subs = [tuple(pair.split("=", 1)) for pair in same]

    def norm(text: str) -> str:
        for old, new in subs:
            text = text.replace(old, new)
        return text

    a_dir, b_dir = before.with_suffix(".demo"), after.with_suffix(".demo")
    left = 0
    for path in sorted(set(listing(a_dir)) & set(listing(b_dir))):
        pa, pb = a_dir / path, b_dir / path
        if pa.read_bytes() == pb.read_bytes() or any(v in path for v in VOLATILE):
            continue
        if pa.suffix.lower() == ".cdf":
            ca, cb = cdflib.CDF(str(pa)), cdflib.CDF(str(pb))
            va, vb = ca.cdf_info().zVariables, cb.cdf_info().zVariables
            what = [f"variables {sorted(set(va) ^ set(vb))}"] if set(va) != set(vb) else []
            for v in sorted(set(va) & set(vb)):
                xa, xb = ca.varget(v), cb.varget(v)
                if not (type(xa) is type(xb) and str(xa) == str(xb)) and not (
                        hasattr(xa, "shape") and getattr(xa, "shape", None) == xb.shape
                        and (xa == xb).all()):
                    what.append(f"variable {v}")
                if norm(str(ca.varattsget(v))) != str(cb.varattsget(v)):
                    what.append(f"attributes of {v}")
            ga, gb = ca.globalattsget(), cb.globalattsget()
            what += [f"global {k}" for k in sorted(set(ga) | set(gb))
                     if norm(str(ga.get(k))) != str(gb.get(k))]
        else:
            try:
                ta, tb = norm(pa.read_text()), pb.read_text()
            except UnicodeDecodeError:
                print(f"binary   {path}")
                left += 1
                continue
            what = [f"line {i + 1}" for i, (x, y) in enumerate(zip(ta.splitlines(),
                                                                   tb.splitlines(),
                                                                   strict=False)) if x != y]
            if len(ta.splitlines()) != len(tb.splitlines()):
                what.append("number of lines")
        if what:
            print(f"content  {path}: {', '.join(what[:6])}{' ...' if len(what) > 6 else ''}")
            left += 1
    print(f"{left} files differ beyond the substitutions {same}")
    return 1 if left else 0


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
    c.add_argument("--explain", action="store_true",
                   help="say what differs inside each file (kept demos)")
    c.add_argument("--same", action="append", default=[], metavar="OLD=NEW",
                   help="text substitution on the before side (with --explain)")
    args = parser.parse_args()
    if args.command == "make":
        make(args.rev, args.target)
        return 0
    if args.explain:
        return explain(args.before, args.after, args.same)
    return compare(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main())
