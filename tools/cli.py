"""`stiffcomp`: one entry point, one module per subcommand.

Each module in COMMANDS defines ``register(subparsers)``, which adds its subcommand and sets
``func(args) -> int`` as the handler. Expected failures (bad files, bad config) print one clear
message and exit with code 2; nothing prints a traceback for user error.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from stiffness.errors import StiffnessError

COMMANDS = [
    "tools.fit_cmd",
    "tools.stiffness_cmd",
    "tools.run_cmd",
    "tools.registers_cmd",
    "tools.record_cmd",
    "tools.payload_cmd",
    "tools.simulate_cmd",
    "tools.compare_cmd",
    "tools.diagnose_cmd",
    "tools.model_cmd",
    "tools.hil_cmd",
]

EXIT_USER_ERROR = 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="stiffcomp",
        description="Stiffness modelling and real-time deformation compensation for industrial robots.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        importlib.import_module(name).register(sub)
    return parser


def user_errors() -> tuple[type[BaseException], ...]:
    """Exception types that mean bad input, reported without a traceback."""
    errors: list[type[BaseException]] = [StiffnessError]
    try:
        from service.errors import ServiceError  # the service may not be installed in a trimmed build
        errors.append(ServiceError)
    except ImportError:
        pass
    return tuple(errors)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except user_errors() as e:
        print(f"stiffcomp {args.command}: error: {e}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
