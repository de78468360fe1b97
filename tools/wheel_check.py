"""Build fluxcal, install the wheel (core, no extras) in a fresh venv and run it.

``make wheel-check`` runs this; ``tests/test_wheel.py`` runs the same steps (slow).

Steps: ``git clone --no-tags`` of HEAD (CI's clean clone: the version falls back to
``0.1.devN+g<hash>``), ``python -m build`` (sdist, then the wheel from the sdist), a fresh
venv, ``pip install <wheel>`` (the core dependencies from the package registry), then in
that venv: no matplotlib, dask, distributed or zarr; ``fluxcal --version``; a simulated
MESSENGER hour through ``fluxcal messenger edr2cdr --formats cdf``; ``--quicklook``
refused in one line with exit code 2.  Prints the installed size of the venv's
site-packages.

Usage: ``python tools/wheel_check.py [--work DIR] [--keep]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Packages the core install must not bring (the plot, batch and zarr extras).
EXTRAS_ONLY = ("matplotlib", "dask", "distributed", "zarr")
#: Seconds of simulated MESSENGER science (20 Hz) for the CDF-only edr2cdr.
SIM_SECONDS = 600


class CheckFailed(RuntimeError):
    """A step of the check failed (the message says which and shows its output)."""


def sh(cmd: list[str], *, cwd: Path | None = None, env: dict | None = None,
       expect: int | None = 0, timeout: float = 900) -> subprocess.CompletedProcess:
    """Run ``cmd``; raise `CheckFailed` unless it exits with ``expect`` (None: any)."""
    run = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=timeout)
    if expect is not None and run.returncode != expect:
        raise CheckFailed(f"{' '.join(map(str, cmd))} exited {run.returncode} "
                          f"(expected {expect}):\n{run.stdout[-2000:]}\n{run.stderr[-3000:]}")
    return run


def registry_reachable(python: str = sys.executable) -> bool:
    """Whether pip can fetch a build dependency (setuptools-scm) from the registry."""
    with tempfile.TemporaryDirectory() as tmp:
        try:
            run = subprocess.run([python, "-m", "pip", "download", "--quiet", "--no-deps",
                                  "--dest", tmp, "setuptools-scm>=8"], capture_output=True,
                                 timeout=120)
        except (OSError, subprocess.TimeoutExpired):
            return False
        return run.returncode == 0


def clean_clone(work: Path) -> Path:
    """Clone the repository's HEAD without tags into ``work/src``."""
    src = work / "src"
    sh(["git", "clone", "--quiet", "--no-tags", "--no-hardlinks", ROOT, src])
    return src


def build(src: Path, work: Path) -> Path:
    """``python -m build`` (sdist, then the wheel from it); return the wheel."""
    dist = work / "dist"
    sh([sys.executable, "-m", "build", "--outdir", dist, src])
    wheels = sorted(dist.glob("fluxcal-*.whl"))
    if len(wheels) != 1 or not list(dist.glob("fluxcal-*.tar.gz")):
        raise CheckFailed(f"expected one wheel and one sdist in {dist}: {os.listdir(dist)}")
    return wheels[0]


def install(wheel: Path, work: Path) -> Path:
    """Make a fresh venv, install ``wheel`` (no extras); return the venv's bin folder."""
    venv = work / "venv"
    sh([sys.executable, "-m", "venv", venv])
    binary = venv / "bin"
    sh([binary / "python", "-m", "pip", "install", "--quiet", wheel])
    return binary


def site_packages_size(binary: Path) -> int:
    """Bytes in the venv's site-packages (what the install added)."""
    site = sh([binary / "python", "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"]
              ).stdout.strip()
    return sum(p.stat().st_size for p in Path(site).rglob("*") if p.is_file()
               and not p.is_symlink())


def run_checks(binary: Path, work: Path, wheel: Path) -> dict[str, str]:
    """Run the installed ``fluxcal`` as a user would; return what was seen."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = f"{binary}{os.pathsep}{env.get('PATH', '')}"
    fluxcal = binary / "fluxcal"
    seen: dict[str, str] = {}
    present = sh([binary / "python", "-c", "import importlib.util as u; print(' '.join("
                  f"m for m in {EXTRAS_ONLY!r} if u.find_spec(m)))"], env=env).stdout.strip()
    if present:
        raise CheckFailed(f"the core install brought extras-only packages: {present}")
    version = sh([fluxcal, "--version"], env=env, cwd=work).stdout.strip()
    wheel_version = wheel.name.split("-")[1]
    if wheel_version not in version:
        raise CheckFailed(f"fluxcal --version says {version!r}; the wheel is {wheel_version}")
    seen["version"] = version
    sim, out = work / "sim", work / "out"
    sh([fluxcal, "-q", "simulate", "messenger", "--out", sim, "--duration", SIM_SECONDS],
       env=env, cwd=work)
    streams = [("--sci", "MAG_science.csv"), ("--heater", "MAG_heater.csv"),
               ("--temperature", "MAG_temperature.csv")]
    args = [a for option, name in streams for a in (option, sim / "inputs" / name)]
    kernels = next((sim / "kernels").glob("*.tm"))
    sh([fluxcal, "-q", "messenger", "edr2cdr", *args, "--kernels", kernels, "--out", out,
        "--formats", "cdf", "--frames", "mso", "--average", "60"], env=env, cwd=work)
    cdfs = sorted(p.name for p in out.glob("*.cdf"))
    if not cdfs or list(out.glob("*.png")):
        raise CheckFailed(f"edr2cdr --formats cdf wrote {sorted(os.listdir(out))}")
    seen["cdf"] = ", ".join(cdfs)
    refused = sh([fluxcal, "messenger", "edr2cdr", *args, "--kernels", kernels, "--out",
                  work / "ql", "--formats", "cdf", "--quicklook"], env=env, cwd=work, expect=2)
    message = refused.stderr.strip()
    if "install fluxcal[plot]" not in message or len(message.splitlines()) != 1:
        raise CheckFailed(f"--quicklook without matplotlib said:\n{refused.stderr}")
    if (work / "ql").exists() and any((work / "ql").iterdir()):
        raise CheckFailed(f"the refused run wrote {os.listdir(work / 'ql')}")
    seen["refusal"] = message
    return seen


def main(argv: list[str] | None = None) -> int:
    """Run every step; print the version, products, refusal and installed size."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, help="work folder (default: a temporary one)")
    parser.add_argument("--keep", action="store_true", help="keep the work folder")
    args = parser.parse_args(argv)
    if not registry_reachable():
        print("wheel-check: the package registry cannot be reached: cannot install the "
              "wheel's dependencies", file=sys.stderr)
        return 2
    work = Path(args.work or tempfile.mkdtemp(prefix="fluxcal-wheel-")).resolve()
    work.mkdir(parents=True, exist_ok=True)
    try:
        wheel = build(clean_clone(work), work)
        binary = install(wheel, work)
        seen = run_checks(binary, work, wheel)
        size = site_packages_size(binary)
    except CheckFailed as exc:
        print(f"wheel-check: FAILED: {exc}", file=sys.stderr)
        return 1
    finally:
        if not args.keep and args.work is None:
            shutil.rmtree(work, ignore_errors=True)
    print(f"wheel: {wheel.name}")
    print(f"fluxcal --version: {seen['version']}")
    print(f"edr2cdr --formats cdf: {seen['cdf']}")
    print(f"--quicklook without the plot extra: {seen['refusal']}")
    print(f"core install (site-packages of the fresh venv): {size / 2**20:.0f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
