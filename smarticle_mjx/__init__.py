"""smarticle-mjx: batched simulation of shape-changing smarticles and their gliders."""

import os as _os

# XLA's concurrency-optimised CPU scheduler was seen to leave every thread
# idle on large vmapped MJX batches; turn it off before JAX initialises.
_FLAG = "--xla_cpu_enable_concurrency_optimized_scheduler=false"
if _FLAG.split("=")[0] not in _os.environ.get("XLA_FLAGS", ""):
    _os.environ["XLA_FLAGS"] = (_os.environ.get("XLA_FLAGS", "") + " " + _FLAG).strip()

# The mjx backend shards a batch across XLA host devices when there are
# several (XLA_FLAGS=--xla_force_host_platform_device_count=N). Not forced:
# with 2 host devices a 1024-lane batch stalled with every thread idle here
# (docs/engine.md), while one device never did.

__version__ = "0.4.19"
