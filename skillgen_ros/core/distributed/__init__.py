"""Distributed generation and evaluation (docs/distributed.md): the attempt index is the work unit.

Pure scheduling and shard bookkeeping here (schedule, shards, run); Ray is imported lazily by
ray_pool only when a run asks for more than one worker or a cluster address.
"""
