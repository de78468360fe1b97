from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

# 2024-01-01T00:00:00 TT2000 is ~7.57e17 ns; tests use nearby epochs with odd nanoseconds.
EPOCH0 = 757_339_269_184_000_123


def make_dataset(n: int = 50, seed: int = 0) -> xr.Dataset:
    rng = np.random.default_rng(seed)
    epoch = EPOCH0 + np.arange(n, dtype=np.int64) * 50_000_001
    return xr.Dataset(
        {
            "B_mso": (("time", "component"), rng.normal(0, 300, (n, 3)),
                      {"units": "nT", "description": "Magnetic field, MSO"}),
            "position": (("time", "component"), rng.normal(0, 5000, (n, 3)),
                         {"units": "km", "description": "Spacecraft position"}),
            "quality": ("time", rng.integers(0, 400, n).astype(np.int32),
                        {"units": "1", "description": "SHC quality flag"}),
            "temperature": ("time", rng.normal(20, 5, n).astype(np.float32),
                            {"units": "degC", "description": "Sensor temperature"}),
            "utc": ("time", np.array([f"2024-001T00:00:{i % 60:02d}.{i:03d}" for i in range(n)]),
                    {"units": "", "description": "UTC"}),
        },
        coords={
            "epoch": ("time", epoch, {"units": "ns", "description": "TT2000"}),
            "component": ("component", np.array(["x", "y", "z"]), {"units": ""}),
        },
        attrs={
            "software": "fluxcal",
            "software_version": "0.1.0",
            "inputs": [{"name": "a.csv", "sha256": "ab" * 32}],  # by name, no folder
            "calibration": {"table2": {"version": "v1"}},
            "kernels": [{"name": "k.tsc", "sha256": "cd" * 32}],
            "command_line": "fluxcal test",
            "creation_time": "2026-01-01T00:00:00Z",
            "mission": "MESSENGER",
            "n_dropped": 3,
        },
    )


@pytest.fixture
def dataset() -> xr.Dataset:
    return make_dataset()
