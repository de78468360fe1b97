import pytest

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels
from tests.missions.messenger._benchmarks import load_benchmark

START = "2012-06-01T00:00:00"


@pytest.fixture(scope="session")
def sim_config():
    # 2 h: rate settings 10, 8, 6, 9, 10 (20, 5, 1, 10, 20 Hz); coarse range over 0.3-0.38;
    # duty cycles 40, 36, 0, 0, 0 (3000 s heater off with a 55 C temperature excursion
    # crossing the T_m breakpoints), 25, 8 (< 10 %: no heater signal, no offset), 44, 30
    return SimulationConfig(start_utc=START, duration_s=7200.0)


@pytest.fixture(scope="session")
def messenger_kernels(tmp_path_factory, sim_config):
    out = tmp_path_factory.mktemp("msgr_kernels")
    # +Y to the Sun for 1000-2500 s after the start (S = 1), -Y otherwise (S = 2)
    return write_messenger_like_kernels(
        out, sim_config.start_utc, sim_config.duration_s + 2000.0,
        plus_y_sunward=[(1000.0, 2500.0)],
    )


@pytest.fixture(scope="session")
def calibration():
    return load_calibration(START)


@pytest.fixture(scope="session")
def simulated(messenger_kernels, sim_config, calibration):
    with KernelPool(messenger_kernels):
        return simulate(sim_config, calibration, SclkKernel.from_pool(-236))


@pytest.fixture(scope="session")
def simulated_files(tmp_path_factory, simulated):
    return write_inputs(simulated, tmp_path_factory.mktemp("msgr_inputs"))


@pytest.fixture(scope="session")
def pulls_bench():
    """``benchmarks/messenger_fit_pulls.py`` as a module, for its functions under test."""
    return load_benchmark("messenger_fit_pulls")
