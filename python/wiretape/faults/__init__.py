"""Fault campaigns (DESIGN.md section 14, docs/faults.md).

``wiretape faults SESSION -- CMD ... {port} ...`` runs CMD once against a
clean replay of SESSION (it must pass), then once per fault case (a fault
kind at an exchange), each against a fresh virtual device, and sorts each run
into ``ok``, ``error``, ``crash`` or ``hang``.

The same cases are there for pytest::

    from wiretape import faults

    @pytest.mark.parametrize("case", faults.cases("scan.wtape", budget=20),
                             ids=lambda case: case.id)
    def test_driver_survives(case):
        with faults.faulty_device("scan.wtape", case) as path:
            ...  # run the driver against path; assert it fails cleanly

A session of several ports (DESIGN §19) has exchanges numbered per
channel: its cases are every channel's (``drop@exchange:3@channel:gps``),
CMD names each channel's device ``{port:NAME}``, and every channel is
replayed, on the session's one clock, with the case's fault (which names
the channel it applies to).

The package holds one job per module: ``cases`` (the kinds, the places a
session has, the cases), ``run`` (faulty devices, running CMD, the
campaign, reproduction lines) and ``report`` (runs and campaigns, the
table, the JSON, merging shards).
"""

from .cases import (KIND_NAMES, KINDS, OUTCOMES, FaultCase, FaultInputError, SessionShape, Shard,
                    _kind_spec, all_cases, cases, check_where, session_channels,
                    session_shape)
from .report import Campaign, Run, merge, read_json, session_digest, table, write_json
from .junit import campaign_xml, write_junit
from .shard import ENGINES, from_engine
from .run import (MAX_TIMEOUT_S, PORT_PLACEHOLDER, REPRO_ADDRESS, REPRO_PORT, CampaignInterrupted,
                  CleanRunFailed, campaign, check_command, faulty_device, faulty_devices,
                  reproduction, run_case)

__all__ = [
    "KINDS", "KIND_NAMES", "OUTCOMES", "MAX_TIMEOUT_S", "PORT_PLACEHOLDER", "REPRO_PORT",
    "REPRO_ADDRESS", "FaultInputError", "Shard", "FaultCase", "SessionShape", "Run", "Campaign",
    "CampaignInterrupted", "CleanRunFailed", "session_channels", "session_shape", "check_where",
    "cases", "all_cases", "faulty_device", "faulty_devices", "check_command", "run_case",
    "reproduction", "campaign", "session_digest", "table", "write_json", "read_json", "merge",
    "campaign_xml", "write_junit", "ENGINES", "from_engine",
]
