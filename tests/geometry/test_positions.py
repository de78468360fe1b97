"""Positions against per-sample spkpos and the seed's own SPICE call sequence (sec. 10)."""

from __future__ import annotations

import numpy as np
import pytest
import spiceypy

from fluxcal.geometry import positions


@pytest.fixture(scope="module")
def epochs(msgr_pool):
    et0 = spiceypy.str2et("2012-06-01T00:00:00")
    return np.sort(et0 + np.random.default_rng(9).uniform(0, 86400, 1200))


@pytest.mark.parametrize(
    ("observer", "frame"),
    [("SUN", "J2000"), ("MERCURY", "MSGR_MSO"), ("MERCURY", "IAU_MERCURY")],
)
def test_positions_match_spkpos(msgr_pool, epochs, observer, frame):
    fast = positions.position("MESSENGER", observer, frame, epochs)
    oracle = positions.position("MESSENGER", observer, frame, epochs, method="oracle")
    # default tolerance 1e-4 km (10 cm), far below the archive's printed precision
    assert np.max(np.abs(fast - oracle)) < 1e-4


def _seed_rtn_oracle(et: float) -> tuple[float, float, float]:
    """seed 000 sec. 10.2, the IDL sequence transcribed call by call."""
    m_pos = spiceypy.spkpos("MESSENGER", et, "J2000", "NONE", "SUN")[0]
    pos_r = spiceypy.vnorm(m_pos)
    state = spiceypy.spkezr("EARTH", et, "J2000", "NONE", "SUN")[0]
    es_norm = spiceypy.vcrss(state[0:3], state[3:6])
    pos_lat = 90 - spiceypy.vsep(es_norm, m_pos) / spiceypy.rpd()
    ve_espl_proj = spiceypy.vperp(state[3:6], state[0:3])
    es_plane = spiceypy.psv2pl(state[0:3], state[0:3], state[3:6])
    m_espl_proj = spiceypy.vprjp(m_pos, es_plane)
    sign = np.sign(spiceypy.vdot(ve_espl_proj, m_espl_proj))
    pos_az = sign * spiceypy.vsep(state[0:3], m_espl_proj) / spiceypy.rpd()
    return pos_r, pos_lat, pos_az


def test_rtn_spherical_matches_seed_sequence(msgr_pool, epochs):
    r, lat, az = positions.rtn_spherical("MESSENGER", epochs)
    for i in range(0, epochs.size, 60):
        r0, lat0, az0 = _seed_rtn_oracle(float(epochs[i]))
        assert r[i] == pytest.approx(r0, abs=1e-4)
        assert lat[i] == pytest.approx(lat0, abs=1e-9)
        assert az[i] == pytest.approx(az0, abs=1e-9)


def test_synthetic_orbit_is_messenger_like(msgr_pool, epochs):
    """12-hour orbit, periapsis altitude 200 km, apoapsis altitude 15,200 km (the
    MESSENGER primary-mission orbit), checked with SPICE's own osculating elements."""
    state = spiceypy.spkezr("MESSENGER", float(epochs[0]), "J2000", "NONE", "MERCURY")[0]
    gm = spiceypy.bodvrd("MERCURY", "GM", 1)[1][0] if spiceypy.bodfnd(199, "GM") else 22031.78
    elts = spiceypy.oscltx(state, float(epochs[0]), gm)
    rp, ecc, period = elts[0], elts[1], elts[10]
    assert rp - 2440.0 == pytest.approx(200.0, abs=1.0)
    assert rp * (1 + ecc) / (1 - ecc) - 2440.0 == pytest.approx(15200.0, abs=5.0)
    assert period / 3600 == pytest.approx(12.0, abs=0.1)
