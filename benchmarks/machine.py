"""Which machine a benchmark ran on, and how much of its CPU time was stolen.

The project's 2-core machine is a virtual machine whose host has changed
between sessions (README, "Performance": AMD EPYC machines on 2026-11-27; an
"Intel(R) Xeon(R) Processor" at 2.0 GHz on 2026-12-02), and the same code's
times differ by 2-3x between them: on 2026-12-02 the unchanged simulator at
its 1-ms step took 3.9-4.8 ms per simulation, of wall and of process CPU time
alike, against 1.64 ms on the evening of 2026-12-01, with the load average
at 0.3-0.8 and 0.2-0.4 % of the CPU time stolen by the hypervisor over the
run.
A load average or a "quiet machine" does not tell these apart; the CPU's
model and the stolen share do. Each benchmark prints both with its times, so
that absolute times from different runs are read with the machine they came
from; ratios measured within one run are unaffected.

Linux only; elsewhere the functions return None.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["cpu_model", "cpu_times", "steal_share"]


def cpu_model() -> str | None:
    """The CPU's model name and clock as the kernel reports them, e.g.
    ``"Intel(R) Xeon(R) Processor, 2000 MHz"`` (first CPU of
    ``/proc/cpuinfo``); None where it is not known."""
    try:
        lines = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    fields: dict[str, str] = {}
    for line in lines:
        if not line.strip():
            break  # the first CPU's block ends here
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    model = fields.get("model name")
    if not model:
        return None
    mhz = fields.get("cpu MHz")
    try:
        return f"{model}, {float(mhz):.0f} MHz" if mhz else model
    except ValueError:
        return model


def cpu_times() -> tuple[int, int] | None:
    """All CPUs' (steal, total) time since boot, in clock ticks.

    Returns
    -------
    tuple of int or None
        From the first line of ``/proc/stat`` (user, nice, system, idle,
        iowait, irq, softirq, steal; guest time is already inside user and
        nice, so it is not added); None where the file or its steal column
        is missing.
    """
    try:
        first = Path("/proc/stat").read_text(encoding="ascii").splitlines()[0].split()
    except (OSError, IndexError):
        return None
    if len(first) < 9 or first[0] != "cpu":
        return None
    ticks = [int(v) for v in first[1:9]]
    return ticks[7], sum(ticks)


def steal_share(before: tuple[int, int] | None, after: tuple[int, int] | None) -> float | None:
    """Share (0-1) of all CPU time between two :func:`cpu_times` readings
    that the hypervisor stole (a virtual CPU ready to run but given no
    core: top's ``st``); None if either reading is missing or no time
    passed."""
    if before is None or after is None:
        return None
    total = after[1] - before[1]
    if total <= 0:
        return None
    return (after[0] - before[0]) / total
