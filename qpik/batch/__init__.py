"""Many full-IK solves: the process pool (or Ray), batches on disk, reachability maps.

- :mod:`.pool`: :func:`solve_many`, :func:`iter_solve`, and how a batch runs
  (:class:`~qpik.batch.pool.BatchOptions`);
- :mod:`.chunks`: what travels to the workers and back; :mod:`.worker`: what a worker
  does; :mod:`.ray`: batches on a Ray cluster;
- :mod:`.files`: results files out (``qpik batch``); :mod:`.target_files`: targets files
  in, and targets as arrays, checked;
- :mod:`.reachability_map`: :func:`reachability` maps of a frame over a box.
"""

from .files import BatchRun, TargetArrays, load_targets, solve_file
from .pool import iter_solve, solve_many
from .ray import RayConnectionError
from .reachability_map import ReachabilityMap, reachability
from .worker import WorkerError

__all__ = [
    "BatchRun",
    "RayConnectionError",
    "ReachabilityMap",
    "TargetArrays",
    "WorkerError",
    "iter_solve",
    "load_targets",
    "reachability",
    "solve_file",
    "solve_many",
]
