"""A small valid campaign, written by hand (not by pneumafit's writer).

Four recordings cover both file formats and the notations of the spec:

1. ``charge_P_1.h5``  charge of chamber P; p_P in bar absolute, p_N in bar
   with ``reference = "gauge"``, T_P in degC.
2. ``flow_N_1.csv``   flow test of chamber N; time in ms, p_N in barg.
3. ``step_1.csv``     closed-loop step; ``Pos [mm]`` mapped onto y, y_ref
   sampled on a few rows only (empty cells elsewhere).
4. ``free_1.csv``     open-loop motion of a single-input rig (u_N derived).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest

CAMPAIGN_TOML = """\
format = "pneumatic-campaign"
version = 1
name = "test-rig"
description = "minimal valid campaign"

[rig]
bore = "32 mm"
rod = "16 mm"
stroke = "500 mm"
dead_volume_P = "20 cm^3"
dead_volume_N = "20 cm^3"
moving_mass = "17 kg"
supply_pressure = "7 bar"
exhaust_pressure = "1.013 bar"
ambient_temperature = "20 degC"

[[recording]]
file = "charge_P_1.h5"
kind = "charge"
chamber = "P"
piston_position = "250 mm"

[[recording]]
file = "flow_N_1.csv"
kind = "flow"
chamber = "N"

[[recording]]
file = "step_1.csv"
kind = "step"
role = "validate"
[recording.controller]
law = "pd"
kp = "60 V/m"
kd = "4 V s/m"
u0 = "0 V"
umax = "10 V"
[recording.columns]
"Pos [mm]" = "y"

[[recording]]
file = "free_1.csv"
kind = "free"
"""

N_CHARGE = 101


def write_charge_h5(path: Path) -> None:
    """The charge recording: 1 s at 100 Hz."""
    t = np.linspace(0.0, 1.0, N_CHARGE)
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "pneumatic-recording"
        f.attrs["version"] = 1
        f.attrs["kind"] = "charge"
        f.attrs["description"] = "charge of chamber P"
        f.create_dataset("time", data=t).attrs["unit"] = "s"
        channels = f.create_group("channels")
        channels.create_dataset("u_P", data=np.where(t < 0.5, 5.0, 0.1)).attrs["unit"] = "V"
        channels.create_dataset("p_P", data=1.013 + 5.0 * (1 - np.exp(-t / 0.1))).attrs["unit"] = (
            "bar"
        )
        p_N = channels.create_dataset("p_N", data=np.zeros_like(t))
        p_N.attrs["unit"] = "bar"
        p_N.attrs["reference"] = "gauge"
        channels.create_dataset("T_P", data=20.0 + 10 * t).attrs["unit"] = "degC"


FLOW_CSV = """\
# flow test, chamber N
time [ms],u_N [V],p_N [barg],qm_N [g/s]
0,1.0,2.0,0.5
10,1.0,2.0,0.51
20,2.0,2.0,1.1
30,2.0,3.0,0.9
"""

STEP_CSV = """\
# step test under PD control
# second comment line
time [s],Pos [mm],y_ref [mm],p_P [bar],p_N [bar],u_P [V]
0.00,100.0,100.0,3.0,3.0,0.0
0.01,100.0,,3.0,3.0,0.0
0.02,100.5,200.0,3.1,2.9,6.0
0.03,102.0,,3.3,2.8,6.0
0.04,105.0,200.0,3.5,2.7,5.9
"""

FREE_CSV = """\
time [s],y [m],u_P [V],v [m/s]
0.0,0.10,0.0,0.0
0.1,0.10,1.0,0.0
0.2,0.11,1.0,0.1
0.3,0.13,-1.0,0.2
"""


def build_valid_campaign(folder: Path) -> Path:
    """Write the valid campaign into ``folder``; return the folder."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "campaign.toml").write_text(CAMPAIGN_TOML)
    write_charge_h5(folder / "charge_P_1.h5")
    (folder / "flow_N_1.csv").write_text(FLOW_CSV)
    (folder / "step_1.csv").write_text(STEP_CSV)
    (folder / "free_1.csv").write_text(FREE_CSV)
    return folder


@pytest.fixture
def campaign_dir(tmp_path: Path) -> Path:
    """A freshly written valid campaign folder."""
    return build_valid_campaign(tmp_path / "campaign")


@pytest.fixture(scope="session")
def build_campaign() -> Callable[[Path], Path]:
    """The builder itself, for tests that need several campaigns."""
    return build_valid_campaign
