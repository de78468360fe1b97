"""``fluxcal simulate messenger --layout batch`` feeds ``fluxcal batch messenger`` (issue 12).

Before: ``simulate messenger`` wrote only the edr2cdr layout (``--layout`` unknown, exit 2)
and the batch found no day.
"""

import logging

from fluxcal.cli import main
from fluxcal.missions.messenger.simulate import read_truth
from fluxcal.products import read_fluxcal_product


def test_simulate_batch_layout_then_batch(tmp_path, capsys, caplog):
    sim, out = tmp_path / "sim", tmp_path / "out"
    assert main(["simulate", "messenger", "--layout", "batch", "--days", "2",
                 "--duration", "600", "--out", str(sim)]) == 0
    assert "fluxcal batch messenger" in capsys.readouterr().out
    with caplog.at_level(logging.WARNING):
        code = main(["batch", "messenger", "--input", str(sim), "--start", "2012-06-01",
                     "--end", "2012-06-02", "--out", str(out), "--formats", "tab",
                     "--scheduler", "serial", "--quiet"])
    assert code == 0, capsys.readouterr()
    for day in ("12153", "12154"):
        prod = read_fluxcal_product(out / f"MAGMSOSCI{day}_V01.TAB")
        truth = read_truth(sim / "truth" / f"MAGTRUTH_20{day}.csv")
        assert prod.sizes["time"] == truth.sizes["time"] > 0
    # issue 12 item: the batch passes the previous day's heater file, whose data start
    # 20 min before the first science: no "give the previous day's heater file" warning
    # unless the duty cycle before the stream really enters a science sample
    text = caplog.text + capsys.readouterr().err
    assert "previous day's heater file" not in text


def test_simulate_batch_layout_refuses_a_start_inside_a_day(tmp_path, capsys):
    code = main(["simulate", "messenger", "--layout", "batch", "--start",
                 "2012-06-01T12:00:00", "--out", str(tmp_path / "sim")])
    err = capsys.readouterr().err
    assert code == 2 and "00:00 UTC" in err and len(err.strip().splitlines()) == 1
