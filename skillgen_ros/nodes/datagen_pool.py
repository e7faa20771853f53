"""datagen's distributed path: a Generate goal with workers > 1 (or a ray_address) runs on Ray.

The node is the Ray driver (core/distributed/run.py): it packs the run's source demos, starts the
workers (in-process envs, or one node graph each in its own ROS_DOMAIN_ID: skillgen_ros/graph_worker.py),
publishes feedback aggregated over the workers, and on a cancel tells every worker to stop: each
abandons the attempt it is in at its next step (a resumed run runs that index again). Parameters: distributed.perception (in-process workers' perception),
distributed.domain_ids (graph workers lease their ROS domains from these, "A-B"; "" = 1-101).
"""
from __future__ import annotations

from skillgen_interfaces.action import Generate


def is_distributed(g) -> bool:
    return int(getattr(g, "workers", 0)) > 1 or bool(getattr(g, "ray_address", "")) or bool(getattr(g, "resume", False))


def declare(node) -> None:
    node.declare_parameter("distributed.perception", "estimate")
    node.declare_parameter("distributed.domain_ids", "")


def check_goal(node, g) -> None:
    """What can be refused before Ray starts: a malformed address, bad domain ids."""
    from skillgen_ros.cli.distributed import parse_domains
    from skillgen_ros.core.distributed.ray_pool import check_address

    check_address(str(g.ray_address))
    parse_domains(str(node.get_parameter("distributed.domain_ids").value))


def run_goal(node, goal_handle, req, demos_dir: str):
    """Run `req` on max(workers, 1) Ray workers; returns core/distributed/run.DistributedResult."""
    from skillgen_ros.cli.distributed import parse_domains
    from skillgen_ros.core.distributed.ray_pool import RayPool
    from skillgen_ros.core.distributed.run import run_distributed
    from skillgen_ros.core.distributed.shards import ShardStore, pack_dir
    from skillgen_ros.core.distributed.worker import WorkerSpec

    g = goal_handle.request
    store = ShardStore(req.output_dir).open(req, bool(g.resume))
    spec = WorkerSpec(mode="in_process" if g.in_process else "graph",
                      perception=str(node.get_parameter("distributed.perception").value),
                      domain_ids=parse_domains(str(node.get_parameter("distributed.domain_ids").value)))

    def progress(p, _statuses):
        goal_handle.publish_feedback(Generate.Feedback(attempts=p.attempts, successes=p.successes,
                                                       success_rate=p.rate, eta_seconds=p.eta_seconds,
                                                       last_reason=p.last_reason))

    def stop():
        return "CANCELED" if goal_handle.is_cancel_requested else ""

    pool = RayPool(max(int(g.workers), 1), spec, req, pack_dir(demos_dir), address=str(g.ray_address),
                   should_abort=stop)
    try:
        return run_distributed(pool, req, on_progress=progress, should_stop=stop, store=store, status_every_s=0.5)
    finally:
        pool.close()
