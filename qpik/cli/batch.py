"""``qpik batch``: solve a file of targets on every core (or on Ray), chunk by chunk."""

from __future__ import annotations

import argparse
import signal
import sys

from ..batch.files import BatchRun, check_out_not_targets, solve_file
from ..batch.worker import WorkerError
from ._common import add_solve_arguments, non_negative_int, solve_options_from_args

#: The exit status of a run a worker's death ended (EX_TEMPFAIL: rerun to resume).
EXIT_WORKER_DIED = 75


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "batch",
        help="solve a file of IK targets on every core or a Ray cluster; resumable",
        description="Solve one IK problem per row of TARGETS (qpik.solve for one frame, "
        "seeded per row) in a process pool or on Ray, and write RESULTS (npz: q, converged, "
        "reason, position_error [m], orientation_error [rad], iterations, restarts_used, "
        "time [s], done; or the same columns in Parquet) chunk by chunk. TARGETS is an "
        ".npz with positions (N, 3) [m] and "
        "optionally quaternions (N, 4, w x y z), world frame, or a .csv with columns x,y,z "
        "and optionally qw,qx,qy,qz. Finished chunks are kept in RESULTS.chunks/ until the "
        "end: rerunning the same command resumes without redoing them. Exit status: 0 every "
        "target solved (converged or not), 2 invalid input, 3 stopped early (--max-chunks), "
        "75 a worker process died (killed), 130 interrupted; rerun to resume (it says how "
        "many targets it skips).",
        epilog="examples: qpik batch targets.npz --robot ur5e --frame ee --out results.npz; "
        "qpik batch targets.csv --robot erd:panda --frame panda_hand --out r.npz --workers 2; "
        "qpik batch targets.npz --robot ur5e --frame ee --out r.npz --ray auto",
    )
    parser.add_argument("targets", metavar="TARGETS", help="targets file (.npz or .csv)")
    parser.add_argument(
        "--robot", required=True, help="bundled name (qpik robots), .xml/.urdf path or erd:NAME"
    )
    parser.add_argument("--frame", required=True, help="target frame (site, body or geom name)")
    parser.add_argument(
        "--out",
        required=True,
        metavar="RESULTS",
        help="results file: .npz, or .parquet (one row per target; needs pyarrow)",
    )
    parser.add_argument(
        "--chunk-size", type=int, default=128, metavar="N", help="targets per chunk (128)"
    )
    parser.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="worker processes (default: every core; with --ray, every CPU of the cluster)",
    )
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run on Ray: 'auto' (the cluster running here), 'ray://HOST:PORT' (Ray Client: "
        "pip install 'ray[client]'), 'HOST:PORT' (from a cluster's node), or 'local' to start "
        "one here (needs the cluster extra: pip install -e '.[cluster]')",
    )
    parser.add_argument("--seed", type=int, default=0, help="batch seed (0)")
    add_solve_arguments(parser, "target")
    parser.add_argument(
        "--max-chunks",
        type=non_negative_int,
        metavar="K",
        help="solve at most K chunks now; rerun to resume (0: only check the inputs and "
        "write RESULTS, every row pending)",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="discard an earlier run over --out"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    options = solve_options_from_args(args)
    check_out_not_targets(args.out, args.targets, "--out")
    previous = _terminate_like_interrupt()
    try:
        run_ = solve_file(
            args.robot,
            args.frame,
            args.targets,
            args.out,
            chunk_size=args.chunk_size,
            seed=args.seed,
            workers=args.workers,
            backend="ray" if args.ray else "process",
            address=None if args.ray in (None, "local") else args.ray,
            max_chunks=args.max_chunks,
            overwrite=args.overwrite,
            progress=not args.quiet,
            **options,
        )
    except KeyboardInterrupt:
        print(
            f"qpik batch: interrupted; finished chunks are kept in {args.out}.chunks/: "
            "run the same command again to resume",
            file=sys.stderr,
        )
        return 130
    except WorkerError as exc:  # (a worker killed: the OOM killer, say; not the input's fault)
        print(
            f"qpik batch: error: {exc}; finished chunks are kept in {args.out}.chunks/: run "
            "the same command again to resume",
            file=sys.stderr,
        )
        return EXIT_WORKER_DIED
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if not args.quiet:
        skipped = skipped_targets(run_)
        if skipped:
            print(_skip_note(run_, skipped))
        print(run_.summary())
    return 0 if run_.complete else 3


def skipped_targets(run_: BatchRun) -> int:
    """How many targets an earlier run over the same ``--out`` had already solved, which
    this run skipped: the rows done now (not ``pending``) less the ones solved now."""
    pending = (run_.reasons or {}).get("pending", 0)
    return run_.total - pending - run_.targets_solved


def _skip_note(run_: BatchRun, skipped: int) -> str:
    """The line that says a rerun skipped targets (all of them: nothing was left to do)."""
    line = (
        f"skipped {skipped} of {run_.total} targets ({run_.chunks_before} chunks): already "
        f"solved in {run_.out} by an earlier run"
    )
    if run_.chunks_solved == 0 and run_.complete:
        line += "; nothing left to do (--overwrite to solve them again)"
    return line


def _raise_interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def _terminate_like_interrupt():
    """SIGTERM (a scheduler's preemption, ``kill``) ends the run like Ctrl-C: finished
    chunks are kept, the workers are stopped. Returns the previous handler (``None`` off
    the main thread, where handlers cannot be set)."""
    try:
        return signal.signal(signal.SIGTERM, _raise_interrupt)
    except ValueError:
        return None
