"""What a MESSENGER day's product holds at its edges (issue 12, decision in
docs/decisions/messenger.md): the UTC day of the recorded (EDR) time, and a last day
recorded within one net lag of its midnight joins the day before.

Before: a run over 23:50-24:00 (true time; the simulator's recorded MET is later by the
Table 1 net lag) wrote a second complete product set for 2012-06-02 holding 2 samples.
"""

import pytest

from fluxcal.cli import main
from fluxcal.products import read_fluxcal_product


def _run(tmp_path, duration: float) -> tuple[list[str], int]:
    sim, out = tmp_path / "sim", tmp_path / "out"
    assert main(["simulate", "messenger", "--out", str(sim), "--start", "2012-06-01T23:50:00",
                 "--duration", str(duration)]) == 0
    inp = sim / "inputs"
    assert main(["messenger", "edr2cdr", "--sci", str(inp / "MAG_science.csv"),
                 "--heater", str(inp / "MAG_heater.csv"),
                 "--temperature", str(inp / "MAG_temperature.csv"),
                 "--kernels", str(sim / "kernels" / "messenger_synthetic.tm"),
                 "--out", str(out), "--formats", "tab", "--average", "60",
                 "--frames", "mso"]) == 0
    n_science = len((inp / "MAG_science.csv").read_text().splitlines()) - 1
    return sorted(p.name for p in out.iterdir()), n_science


def test_lag_sized_tail_joins_the_day(tmp_path, caplog):
    names, n = _run(tmp_path, 600.0)
    assert not [x for x in names if "12154" in x], names  # no second product set
    prod = read_fluxcal_product(tmp_path / "out" / "MAGMSOSCI12153_V01.TAB")
    assert prod.sizes["time"] == n  # every sample in the one day's product
    # the last sample is past midnight (its corrected time too): held, not dropped
    last = {k: int(prod[k].values[-1]) for k in ("year", "doy", "hour", "minute")}
    assert last == {"year": 2012, "doy": 154, "hour": 0, "minute": 0}
    assert float(prod["second"].values[-1]) < 2.358
    assert "join the previous day's product" in caplog.text


@pytest.mark.parametrize("duration", [630.0])
def test_a_real_next_day_keeps_its_own_products(tmp_path, duration):
    # 30 s recorded after midnight (> 2.358 s, the largest net lag): a day of its own
    names, n = _run(tmp_path, duration)
    assert "MAGMSOSCI12154_V01.TAB" in names and "MAGMSOSCI12153_V01.TAB" in names
    a = read_fluxcal_product(tmp_path / "out" / "MAGMSOSCI12153_V01.TAB").sizes["time"]
    b = read_fluxcal_product(tmp_path / "out" / "MAGMSOSCI12154_V01.TAB").sizes["time"]
    assert a + b == n and b > 2
