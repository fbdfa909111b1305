"""Campaign format version 1: read, validate, write and check rig data.

A campaign is a folder with a ``campaign.toml`` (rig and list of recordings)
and one HDF5 or CSV file per recording; see ``docs/campaign-format.md``.
All values handed to the rest of pneumafit are SI floats, pressures absolute.
"""

from pneumafit.campaign.check import check_campaign
from pneumafit.campaign.errors import CampaignError, PneumafitInputError, Problem
from pneumafit.campaign.model import (
    CHAMBERS,
    CHANNELS,
    INPUT_CHANNELS,
    KINDS,
    ROLES,
    Campaign,
    PDController,
    Recording,
    Rig,
    required_channels,
)
from pneumafit.campaign.reader import (
    CampaignReport,
    inspect_campaign,
    read_campaign,
    read_recording,
    summarize,
    validate_campaign,
)
from pneumafit.campaign.units import parse_unit, parse_value, ureg
from pneumafit.campaign.writer import write_campaign, write_recording_csv, write_recording_h5

__all__ = [
    "CHAMBERS",
    "CHANNELS",
    "INPUT_CHANNELS",
    "KINDS",
    "ROLES",
    "Campaign",
    "CampaignError",
    "CampaignReport",
    "PDController",
    "PneumafitInputError",
    "Problem",
    "Recording",
    "Rig",
    "check_campaign",
    "inspect_campaign",
    "parse_unit",
    "parse_value",
    "read_campaign",
    "read_recording",
    "required_channels",
    "summarize",
    "ureg",
    "validate_campaign",
    "write_campaign",
    "write_recording_csv",
    "write_recording_h5",
]
