"""A MESSENGER run is written all or nothing (issue 3 "Nothing is written for a day that
failed", issue 6 atomic writes, issue 32 declared products): failures injected after the
first product, in the 4th frame's product, in the quicklook, and by the sec. 13
validation (a failed day is refused, the other days are written)."""

import pytest

import fluxcal.missions.messenger.products as msgr_products
import fluxcal.products.declared as declared
import fluxcal.products.quicklook as quicklook
from fluxcal.errors import ValidationError
from fluxcal.missions.messenger.routes import run_edr2cdr

FRAMES = ("mso", "j2000", "mbf", "rtn", "sc")


class Injected(RuntimeError):
    pass


def _run(files, kernels, out, **kw):
    kw.setdefault("frames", FRAMES)
    kw.setdefault("averages", (60,))
    kw.setdefault("formats", ("tab", "cdf", "png"))
    return run_edr2cdr([files["science"]], [files["heater"]], [files["temperature"]],
                       kernels, out, **kw)


def _listing(folder):
    """Every entry of the folder, temporaries (dot files) included."""
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def test_failure_after_the_first_product_writes_nothing(tmp_path, monkeypatch,
                                                         simulated_files, messenger_kernels):
    real = declared.write_product
    calls = []

    def failing(*args, **kwargs):
        calls.append(args[1])
        if len(calls) == 2:  # the first product (TAB, LBL, cdf) is complete by now
            raise Injected("disk full")
        return real(*args, **kwargs)

    monkeypatch.setattr(declared, "write_product", failing)
    out = tmp_path / "out"
    with pytest.raises(Injected):
        _run(simulated_files, messenger_kernels, out)
    assert len(calls) == 2
    assert _listing(out) == []


def test_failure_in_the_fourth_frame_writes_nothing(tmp_path, monkeypatch, simulated_files,
                                                    messenger_kernels):
    real = msgr_products.product_dataset
    seen = []

    def failing(ds, frame):
        seen.append(frame)
        if frame == FRAMES[3]:
            raise Injected(f"cannot build the {frame} product")
        return real(ds, frame)

    monkeypatch.setattr(msgr_products, "product_dataset", failing)
    out = tmp_path / "out"
    with pytest.raises(Injected):
        _run(simulated_files, messenger_kernels, out)
    assert seen == list(FRAMES[:4])
    assert _listing(out) == []


def test_failing_quicklook_writes_nothing_and_keeps_the_old_day(tmp_path, monkeypatch,
                                                                simulated_files,
                                                                messenger_kernels):
    out = tmp_path / "out"
    first = _run(simulated_files, messenger_kernels, out, frames=("mso",), formats=("tab",))
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {p.name for p in first} == set(before)

    def failing(*args, **kwargs):
        raise Injected("quicklook failed")

    monkeypatch.setattr(quicklook, "write_quicklooks", failing)
    with pytest.raises(Injected):
        _run(simulated_files, messenger_kernels, out, frames=("mso",), formats=("tab",),
             quicklook=True)
    # the earlier products are intact, nothing new (no temporaries) appeared
    assert _listing(out) == sorted(before)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_validation_failure_writes_nothing(tmp_path, simulated_files, messenger_kernels):
    out = tmp_path / "out"
    with pytest.raises(ValidationError, match="12153"):
        _run(simulated_files, messenger_kernels, out, max_offset_step=1e-3, quicklook=True)
    assert _listing(out) == []


def test_success_writes_every_file_of_the_day(tmp_path, simulated_files, messenger_kernels):
    out = tmp_path / "out"
    written = _run(simulated_files, messenger_kernels, out, quicklook=True)
    # 5 frames x (full + 60-s average) x (TAB, LBL, cdf) + report (txt, png) + quicklook
    assert len(written) == 5 * 2 * 3 + 2 + 1
    assert _listing(out) == sorted(p.name for p in written)

