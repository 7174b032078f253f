"""``hybridtrack fit FILE --config CONFIG.toml --out TUNED.toml [--id ID …] [--max-objects N] [--hold NAME …] [--max-iterations N] [--json]``: fit a
tracker configuration's parameters to a file by maximum likelihood.

Estimates the measurement noise σ (and the reported course and speed's σ_χ, σ_s where CONFIG measures them), the
white-acceleration density q, each mode's own densities and the mean time in each mode of CONFIG's
multiple-model tracker over FILE's objects (:mod:`hybridtrack.apps.fitting`), prints them with their standard
errors and writes TUNED.toml: CONFIG with those values set, which ``hybridtrack track`` runs.

Exit status: 0 done; 2 a user error, one line on stderr (missing file or configuration, a configuration that
is not of a multiple-model algorithm, no object to fit, an ``--out`` that is a folder or in a missing one).
"""

from __future__ import annotations

import argparse
import json

from hybridtrack.cli import UsageError, check_output_file
from hybridtrack.core.hookspecs import hookimpl


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE", help="position file (as for hybridtrack track)")
    parser.add_argument("--config", required=True, metavar="CONFIG.toml", help="the tracker configuration to start from")
    parser.add_argument("--out", required=True, metavar="TUNED.toml", help="the fitted configuration to write")
    parser.add_argument("--id", action="append", dest="ids", metavar="ID", help="fit on this object only (repeatable)")
    parser.add_argument("--max-objects", type=int, metavar="N", help="fit on the first N objects")
    parser.add_argument(
        "--hold", action="append", default=[], metavar="NAME", help="keep this parameter at CONFIG's value (repeatable; e.g. course_sigma)"
    )
    parser.add_argument("--max-iterations", type=int, metavar="N", help="stop the optimizer after N iterations (default 60)")
    parser.add_argument("--json", action="store_true", help="print the fit as JSON")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from hybridtrack.apps.fitting import describe, fit_config, write_fitted

    if args.max_objects is not None and args.max_objects < 1:
        raise UsageError(f"--max-objects {args.max_objects}: expected a positive number of objects")
    if args.max_iterations is not None and args.max_iterations < 1:
        raise UsageError(f"--max-iterations {args.max_iterations}: expected a positive number of iterations")
    if not Path(args.file).is_file():
        raise UsageError(f"{args.file}: no such position file")
    check_output_file("--out", args.out, "a file (the fitted configuration, TOML)")  # before the fit, not after it
    try:
        limit = {} if args.max_iterations is None else {"max_iterations": args.max_iterations}
        result = fit_config(args.file, args.config, ids=args.ids, max_objects=args.max_objects, hold=args.hold, **limit)
        write_fitted(args.config, result.values, args.out)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.json:
        fields = ("values", "standard_errors", "loglik", "start_loglik", "objects", "reports", "evaluations", "converged")
        print(json.dumps({key: getattr(result, key) for key in fields}, indent=2))
    else:
        print(f"fitted on {result.objects} object(s), {result.reports} reports: ln L {result.start_loglik:.1f} → {result.loglik:.1f}")
        for name, value in result.values.items():
            table, key, units = describe(name)
            print(f"  [{table}] {key:<14} {value:12.6g} ± {result.standard_errors[name]:.3g} {units}")
        if not result.converged:
            print("not converged: the optimizer stopped at its iteration limit (--max-iterations); the values are where it stopped")
        print(f"written: {args.out}")
    return 0


@hookimpl
def register_commands(commands):
    commands.add("fit", "fit a tracker configuration's noise and sojourn times to a file (maximum likelihood)", configure, run)
