"""The fit benchmark's time split and the speed-up model built on it (issue 34, item 7).

``benchmarks/messenger_fit.py`` splits a serial and a Dask fit per pass (`_serial_parts`,
`_dask_parts`, from `fit_passes.fit_days`'s timing records and Dask's task stream);
``benchmarks/messenger_fit_amdahl.py`` projects the speed-up on N workers from those parts
(docs/decisions/messenger_fit.md entry 53).  No timing is asserted here: the
inputs are made-up records, and the expected values are worked out by hand from them
(sums and differences of the given times), from Amdahl's law ``1 / (f + (1 - f) / c)``
in closed form, and, for the uneven days, from order statistics drawn directly with
numpy.  Tolerances: 1e-12 where the same arithmetic is done by hand; the sampling error of
the draws for the simulated list scheduling.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.missions.messenger._benchmarks import BENCHMARKS, load_benchmark


def _load(name: str, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))  # messenger_fit.py imports _control beside it
    return load_benchmark(name)


@pytest.fixture
def fit_bench(monkeypatch):
    return _load("messenger_fit", monkeypatch)


@pytest.fixture
def amdahl(monkeypatch):
    return _load("messenger_fit_amdahl", monkeypatch)


def test_union_of_spans(fit_bench):
    # [0, 2] and [1, 3] overlap in [1, 2]; [5, 6] apart; [5.5, 5.7] inside it
    assert fit_bench._union([(1.0, 3.0), (0.0, 2.0), (5.0, 6.0), (5.5, 5.7)]) == 4.0
    assert fit_bench._union([]) == 0.0


def test_serial_parts_from_timing_records(fit_bench):
    # two passes: reduce 0->3 s (CPU 0->2.5), merge to 3.5 (2.9), client to the next
    # start at 5 (4.0); then 5->7 (4.0->5.8), 7->7.2 (5.8->6.0), end 9 (7.5)
    passes = [{"start": 0.0, "reduced": 3.0, "gathered": 3.5, "start_cpu": 0.0,
               "reduced_cpu": 2.5, "gathered_cpu": 2.9},
              {"start": 5.0, "reduced": 7.0, "gathered": 7.2, "start_cpu": 4.0,
               "reduced_cpu": 5.8, "gathered_cpu": 6.0}]
    parts = fit_bench._serial_parts(-0.5, 9.0, 7.5, passes)
    assert parts["setup_s"] == 0.5
    assert parts["reduce_s"] == [3.0, 2.0]
    assert parts["merge_s"] == pytest.approx([0.5, 0.2], abs=1e-12)
    assert parts["client_s"] == pytest.approx([1.5, 1.8], abs=1e-12)
    assert parts["reduce_cpu_s"] == pytest.approx([2.5, 1.8], abs=1e-12)
    assert parts["merge_cpu_s"] == pytest.approx([0.4, 0.2], abs=1e-12)
    assert parts["client_cpu_s"] == pytest.approx([1.1, 1.5], abs=1e-12)


def _task(name: str, worker: str, start: float, stop: float, compute_s: float, *,
          transfer_s: float = 0.0) -> dict:
    """One task-stream record as `_dask_parts` reads it (times in s)."""
    return {"name": name, "worker": worker, "start": start, "stop": stop,
            "compute_s": compute_s, "transfer_s": transfer_s}


def test_dask_parts_from_the_task_stream(fit_bench):
    # one pass on 2 workers: the reduce window 10..14 (gathered), the client to 16
    passes = [{"start": 10.0, "reduced": 13.5, "gathered": 14.0}]
    tasks = [
        _task("reduce_chunk", "a", 10.2, 11.2, 1.0),
        _task("reduce_chunk", "b", 10.1, 11.6, 1.5),
        _task("reduce_chunk", "a", 11.3, 12.5, 1.2),
        _task("merge_parts", "b", 12.6, 12.9, 0.3, transfer_s=0.1),
        _task("resample_fits", "a", 14.5, 15.0, 0.5),
        _task("resample_fits", "b", 14.6, 15.2, 0.6),
    ]
    (p,) = fit_bench._dask_parts(16.0, passes, tasks, n_workers=2)
    assert p["days"] == 3 and p["merges"] == 1
    assert p["day_compute_s"] == pytest.approx(3.7, abs=1e-12)
    assert p["merge_compute_s"] == pytest.approx(0.3, abs=1e-12)
    assert p["transfer_s"] == pytest.approx(0.1, abs=1e-12)
    assert p["reduce_wall_s"] == 4.0
    # 4 s of wall less (3.7 + 0.3) / 2 worker-seconds computed
    assert p["idle_s"] == pytest.approx(2.0, abs=1e-12)
    assert p["first_task_s"] == pytest.approx(0.1, abs=1e-12)
    assert p["tail_s"] == pytest.approx(14.0 - 12.5, abs=1e-12)
    assert p["client_wall_s"] == 2.0
    assert p["resamples"] == 2
    assert p["resample_compute_s"] == pytest.approx(1.1, abs=1e-12)
    assert p["resample_union_s"] == pytest.approx(15.2 - 14.5, abs=1e-12)


def _params(**over):
    p = {"passes": 3, "w": 0.5, "w_workers": 0.5, "m": 0.05, "m_workers": 0.05,
         "s": 0.4, "s_own": 0.4, "b": 0.0, "z": 0.2, "o_rs": 0.0, "setup": 0.1,
         "first": 0.0, "gap": 0.0, "tail": 0.0}
    p.update(over)
    return p


def test_tail_share_by_hand(amdahl):
    """The merges left after the last day, counted on the tree of groups of four."""
    assert amdahl.tail_share(1) == 0.0  # nothing to merge
    assert amdahl.tail_share(4) == 1.0  # one merge, after the last day
    # 5 days: (1+1+1+1) then (4+1); day 5 waits only for the second: 5 of 4 + 5
    assert amdahl.tail_share(5) == pytest.approx(5 / 9, abs=1e-15)
    # 8 days: 4 + 4, then 8; the last group of four and the top: 4 + 8 of 16
    assert amdahl.tail_share(8) == pytest.approx(12 / 16, abs=1e-15)
    # 64 days: levels of 64, 64 and 64 days merged; the chain holds 4 + 16 + 64
    assert amdahl.tail_share(64) == pytest.approx(84 / 192, abs=1e-15)


@pytest.mark.parametrize("control", [1.0, 1.9, 13.54])
def test_model_without_overheads_is_amdahl(amdahl, control):
    """No waits, gaps, uneven days or resamples: Amdahl's law with the serial share.

    The merges on the chain after the last day (84 of 192 day-merges at 64 days, as
    worked out in `test_tail_share_by_hand`) are the merge tree's tail: serial.
    """
    chain = 84 / 192 * 0.05
    p, days = _params(tail=chain), 64
    t1, tn, _ = amdahl.model(p, days, 16, control, spread_extra=0.0)
    serial = 0.1 + 3 * (0.4 + chain) + 0.2
    parallel = 3 * (64 * 0.5 + 0.05 - chain)
    f = serial / (serial + parallel)
    assert t1 == pytest.approx(serial + parallel, rel=1e-12)
    assert t1 / tn == pytest.approx(1.0 / (f + (1.0 - f) / control), rel=1e-12)


def test_model_overheads_add_per_pass(amdahl):
    """Each overhead enters every pass once; the resamples divide by the control."""
    p = _params(w_workers=0.6, m_workers=0.08, s_own=0.3, b=0.2, o_rs=0.05, first=0.04,
                gap=0.003, tail=0.07)
    days, workers, control = 8, 4, 3.0
    t1, tn, parts = amdahl.model(p, days, workers, control, spread_extra=0.5)
    per_pass = (8 * 0.6 + (1 - 12 / 16) * 0.08) / 3.0 + 0.04 + 0.003 * (8 + 8 / 3) / 4 \
        + 0.5 * 0.6 + 0.07 + 0.3 + 0.2 / 3.0 + 0.05
    assert sum(parts.values()) == pytest.approx(per_pass, rel=1e-12)
    assert tn == pytest.approx(0.1 + 3 * per_pass + 0.2, rel=1e-12)
    assert t1 == pytest.approx(0.1 + 3 * (8 * 0.5 + 0.05 + 0.4) + 0.2, rel=1e-12)


@pytest.mark.parametrize("control", [1.0, 13.54])
def test_once_per_fit_work_adds_to_both_runs_once(amdahl, control):
    """``Z`` is serial in both runs: it adds itself to T1 and to TN, once per fit."""
    without = amdahl.model(_params(z=0.0), 64, 16, control, spread_extra=0.1)
    with_z = amdahl.model(_params(z=1.3), 64, 16, control, spread_extra=0.1)
    assert with_z[0] - without[0] == pytest.approx(1.3, abs=1e-12)
    assert with_z[1] - without[1] == pytest.approx(1.3, abs=1e-12)


def test_once_per_fit_read_from_the_benchmark(amdahl):
    """``z`` is messenger_fit.py's ``once_per_fit`` total; a written fit's last pass holds it.

    A refused fit's passes are taken as they are (3 passes: 0.64, 0.64, 0.84 CPU s serially,
    0.35, 0.35, 0.55 on Dask); a written one's last pass less ``z`` (0.5 CPU s).
    """
    refused = {**_run(4, 1, 1.0, 8.0, 8.0, 0), "outcome": "refused: not converged",
               "once_per_fit": {"total_cpu_s": 0.5}}
    q = amdahl.parts(refused)
    assert q["z"] == 0.5 and not q["written"]
    assert q["s"] == pytest.approx((0.64 + 0.64 + 0.84) / 3, abs=1e-12)
    assert q["s_own"] == pytest.approx((0.35 + 0.35 + 0.55) / 3, abs=1e-12)
    written = {**refused, "outcome": "written", "outcome_parallel": "written"}
    q = amdahl.parts(written)
    assert q["z"] == 0.5 and q["written"]
    assert q["s"] == pytest.approx((0.64 + 0.64 + 0.34) / 3, abs=1e-12)
    assert q["s_own"] == pytest.approx((0.35 + 0.35 + 0.05) / 3, abs=1e-12)
    assert amdahl.parts(_run(4, 1, 1.0, 8.0, 8.0, 0))["z"] == 0.0  # a file without it


def test_uneven_days_against_order_statistics(amdahl):
    """One day per worker: the extra is E[max] - E[mean] of the workers' days."""
    assert amdahl.imbalance(64, 1, 0.2, np.random.default_rng(0)) == 0.0
    assert amdahl.imbalance(64, 16, 0.0, np.random.default_rng(0)) == 0.0
    spread, n = 0.2, 8
    k = 1.0 / spread ** 2
    draws = np.random.default_rng(1).gamma(k, 1.0 / k, (200_000, n))
    expected = float(np.mean(draws.max(axis=1) - draws.mean(axis=1)))
    got = amdahl.imbalance(n, n, spread, np.random.default_rng(2), draws=4000)
    # the draws' own standard error: sd(max - mean) ~ 0.09 / sqrt(4000) ~ 0.0015
    assert got == pytest.approx(expected, abs=0.006)
    # four days per worker: within Graham's bound for list scheduling, makespan <= sum / N
    # + (1 - 1 / N) t_max, so the extra is at most (1 - 1/N) E[t_max] of the 32 days
    four = amdahl.imbalance(4 * n, n, spread, np.random.default_rng(3), draws=1000)
    t_max = float(np.mean(np.random.default_rng(4).gamma(k, 1.0 / k, (20_000, 4 * n))
                          .max(axis=1)))
    assert 0.0 < four <= (1.0 - 1.0 / n) * t_max


def _run(days, workers, control, serial_s, parallel_s, seed):
    """A made-up messenger_fit.py result in its JSON layout (3 passes)."""
    rng = np.random.default_rng(seed)
    day = list(0.5 + 0.05 * rng.standard_normal(days))
    dask_parts = [{"days": days, "day_s": day, "day_compute_s": sum(day), "merges": 1,
                   "merge_compute_s": 0.05, "transfer_s": 0.0,
                   "reduce_wall_s": sum(day) / workers + 0.1, "idle_s": 0.05 + 0.002 * days,
                   "first_task_s": 0.03, "tail_s": 0.06, "client_wall_s": 0.7,
                   "resamples": workers, "resample_compute_s": 0.3,
                   "resample_union_s": 0.3 / workers} for _ in range(3)]
    return {"days": days, "workers": workers, "samples": days * 86400, "control": control,
            "serial_s": serial_s, "parallel_s": parallel_s, "speed_up": serial_s / parallel_s,
            "serial_parts": {"setup_s": 0.02, "reduce_s": [0.5 * days] * 3,
                             "merge_s": [0.05] * 3, "client_s": [0.7, 0.7, 0.9],
                             "reduce_cpu_s": [0.5 * days] * 3, "merge_cpu_s": [0.05] * 3,
                             "client_cpu_s": [0.6 + 0.01 * days] * 2 + [0.8 + 0.01 * days]},
            "dask_parts": dask_parts,
            "dask_client_cpu": {"reduce_cpu_s": [0.1] * 3, "gather_cpu_s": [0.01] * 3,
                                "client_cpu_s": [0.35] * 2 + [0.55]},
            "worker_cpu": {"reduce_chunk:thread-cpu": 3 * 0.5 * days,
                           "merge_parts:thread-cpu": 0.15,
                           "resample_fits:thread-cpu": 0.9}}


@pytest.mark.slow
def test_once_per_fit_times_what_fit_days_and_run_fit_do(fit_bench, tmp_path):
    """The benchmark's once-per-fit steps: the column errors ``fit_days`` stated, the folder
    and the pictures ``run_fit`` writes; the total is the steps' sum.

    Two simulated days of the benchmark's world, one pass with the guards off (its column
    errors are stated from the base table, which the step is given).
    """
    from fluxcal.extras import available
    from fluxcal.missions.messenger.calibration_data import load_calibration
    from fluxcal.missions.messenger.fit_cli import parse_days
    from fluxcal.missions.messenger.fit_passes import day_chunks, fit_days
    from fluxcal.missions.messenger.fit_waveforms import waveform_column_errors
    from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight

    run = simulate_flight(tmp_path / "sim", FlightConfig(start="2010-03-01", days=2,
                                                         rate_setting=6), truth=False)
    chunks = day_chunks(run.input_dir, parse_days("", run.input_dir))
    base = load_calibration(chunks[0].label, None)
    result = fit_days(chunks, base, passes=1, estimator="variance", guard=False)
    # what the step recomputes is what fit_days stated, bit for bit
    again = waveform_column_errors(result.stats, base)
    assert again.tobytes() == np.asarray(result.waveform_error).tobytes()
    once = fit_bench.once_per_fit(result, base, tmp_path / "out")
    steps = once["steps"]
    assert list(steps) == ["column_errors", "merit", "folder", "report", "pictures"]
    assert once["total_cpu_s"] == pytest.approx(sum(v[1] for v in steps.values()), abs=1e-12)
    assert once["total_s"] == pytest.approx(sum(v[0] for v in steps.values()), abs=1e-12)
    assert all(v[0] >= 0.0 and v[1] >= 0.0 for v in steps.values())
    names = {p.name for p in (tmp_path / "out").iterdir()}
    assert {"fit_report.txt", "fit_report.toml", "index.html"} <= names
    assert any(n.startswith("offsets_temperature_v") for n in names)
    if available("plot"):
        assert "fit_offsets_temperature.png" in names


def test_amdahl_report_runs_on_saved_results(amdahl, tmp_path, monkeypatch, capsys):
    files = []
    for i, (days, workers) in enumerate([(4, 1), (8, 1), (4, 2), (8, 2)]):
        path = tmp_path / f"d{days}_w{workers}.json"
        path.write_text(json.dumps([_run(days, workers, float(workers) * 0.95,
                                         2.0 * days, 2.0 * days / workers, i)]))
        files.append(str(path))
    monkeypatch.setattr("sys.argv", ["messenger_fit_amdahl.py", *files, "--boot", "5",
                                     "--json", str(tmp_path / "out.json")])
    amdahl.main()
    out = capsys.readouterr().out
    assert "vectors/s" in out and "Projection: 64 days on 16 workers" in out
    saved = json.loads((tmp_path / "out.json").read_text())
    assert len(saved["checks"]) == 4
    assert {p["control"] for p in saved["projections"]} == {13.54, 9.92}


def test_amdahl_refuses_without_a_one_worker_run(amdahl, tmp_path, monkeypatch, capsys):
    path = tmp_path / "d4_w2.json"
    path.write_text(json.dumps([_run(4, 2, 1.9, 8.0, 4.5, 0)]))
    monkeypatch.setattr("sys.argv", ["messenger_fit_amdahl.py", str(path)])
    with pytest.raises(SystemExit) as exc:
        amdahl.main()
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("messenger_fit_amdahl: error: ") and str(path) in err
    assert len(err.splitlines()) == 1
