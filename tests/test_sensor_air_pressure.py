"""The air pressure sensor in the probe world (probe_helpers.py) against the US Standard Atmosphere
1976, whose tables give 5 significant digits (±1 Pa at 1 km, ±0.0005 kg/m³ for the sea-level density
whose hydrostatic slope −ρg is checked)."""

from __future__ import annotations

from pathlib import Path

import pytest
from probe_helpers import probe, sensor

SEA_LEVEL_PA = 101325.0
TABLE_1000_M_PA = 89876.0  # US Standard Atmosphere 1976 at 1000 m geometric altitude
SEA_LEVEL_DENSITY = 1.2250  # kg/m³, the same table


def test_air_pressure_follows_the_standard_atmosphere(tmp_path: Path) -> None:
    """101325 Pa at sea level; −ρ₀·g per metre just above it; the 1976 table's 89876 Pa at 1 km
    (through `<reference_altitude>` 1000 on a sensor at z 0)."""
    sensors = sensor("baro", "air_pressure", pose="0 0 -0.5 0 0 0") + sensor(
        "km", "air_pressure", "<air_pressure><reference_altitude>1000</reference_altitude></air_pressure>",
        "0 0 -0.5 0 0 0",
    )  # fmt: skip
    with probe(tmp_path, sensors) as sim:
        sim.teleport((0.0, 0.0, 0.5))  # the sensors at z 0
        sea, km = sim.sample("baro"), sim.sample("km", 0)
        sim.teleport((0.0, 0.0, 10.5))
        ten = sim.sample("baro")
    assert sea.fluid_pressure == pytest.approx(SEA_LEVEL_PA, abs=1e-6)
    assert km.fluid_pressure == pytest.approx(TABLE_1000_M_PA, abs=1.0)
    slope = (ten.fluid_pressure - sea.fluid_pressure) / 10.0
    assert slope == pytest.approx(-SEA_LEVEL_DENSITY * 9.80665, abs=0.01)
    assert sea.variance == 0.0 and sea.header.frame_id == "baro"
