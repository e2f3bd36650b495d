"""What this process may still allocate, and the check every large allocation of rbody passes first.

available_memory() is the least of what the machine, the process's address-space limit and its control group
leave: Linux MemAvailable (or the free pages), RLIMIT_AS (ulimit -v) less the address space already mapped,
RLIMIT_DATA less the data already mapped, and a cgroup's memory.max less its memory.current (a container's
limit, which MemAvailable does not see). A run whose estimated peak passes MEMORY_FRACTION of it is refused
before it allocates (rbody.simulation.refuse_large), and so is a batch of a scene factory whose arrays would not
fit (refuse_batch_memory), so that no allocation fails half-way through (or the machine swaps).
"""

from __future__ import annotations

import os
import resource

MEMORY_FRACTION = 0.8  # of the memory available now that an estimated peak may take (the estimate is generous)


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _status_bytes(field: str) -> int | None:
    """A size from /proc/self/status (VmSize: the address space mapped; VmData: the data segment), or None."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _limit_left(limit: int, field: str) -> int | None:
    try:
        soft, _ = resource.getrlimit(limit)
    except (ValueError, OSError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    used = _status_bytes(field)
    return max(0, soft - (used or 0))


def _cgroup_left() -> int | None:
    """memory.max - memory.current of this process's cgroup (v2), or the v1 limit less its usage; None if none."""
    for limit_file, usage_file in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                   ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                    "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        try:
            with open(limit_file) as handle:
                text = handle.read().strip()
            if text == "max":
                continue
            limit = int(text)
            if limit >= 1 << 60:  # v1's "no limit"
                continue
            with open(usage_file) as handle:
                usage = int(handle.read().strip())
            return max(0, limit - usage)
        except (OSError, ValueError):
            continue
    return None


def available_memory() -> int | None:
    """Bytes this process can still allocate now (module docstring), or None when nothing can be read."""
    found = [value for value in (_meminfo_available(), _limit_left(resource.RLIMIT_AS, "VmSize"),
                                 _limit_left(resource.RLIMIT_DATA, "VmData"), _cgroup_left()) if value is not None]
    return min(found) if found else None


def memory_problem(size: float, what: str) -> str | None:
    """Why `size` bytes (an estimated peak) cannot be allocated now (str, with the figures), or None."""
    free = available_memory()
    if free is None or size <= MEMORY_FRACTION * free:
        return None
    return (f"{what} needs about {size / 1e9:.3g} GB, more than {MEMORY_FRACTION:g} of the {free / 1e9:.3g} GB this "
            "process can still allocate (the machine's available memory, and any ulimit or container limit)")


__all__ = ["available_memory", "memory_problem", "MEMORY_FRACTION"]
