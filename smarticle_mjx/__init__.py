"""smarticle-mjx: batched simulation of shape-changing smarticles and their gliders."""

import os as _os

# XLA's concurrency-optimised CPU scheduler was seen to leave every thread
# idle on large vmapped MJX batches; turn it off before JAX initialises.
_FLAG = "--xla_cpu_enable_concurrency_optimized_scheduler=false"
if _FLAG.split("=")[0] not in _os.environ.get("XLA_FLAGS", ""):
    _os.environ["XLA_FLAGS"] = (_os.environ.get("XLA_FLAGS", "") + " " + _FLAG).strip()

# One XLA host device per core, so the mjx backend can shard a batch across
# cores (a single CPU device ran MJX on one core only). Respect a user's
# own setting.
if "xla_force_host_platform_device_count" not in _os.environ.get("XLA_FLAGS", ""):
    _os.environ["XLA_FLAGS"] += f" --xla_force_host_platform_device_count={_os.cpu_count() or 1}"

__version__ = "0.1.0"
