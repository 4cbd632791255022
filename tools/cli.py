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

# subcommand -> the module that registers it. Only the module of the command being run is
# imported (the service's, the plots' and the protocols' imports cost a second); help imports all.
COMMANDS = {
    "fit": "tools.fit_cmd",
    "kcart": "tools.kcart_cmd",
    "torques": "tools.torques_cmd",
    "run": "tools.run_cmd",
    "reload": "tools.reload_cmd",
    "health": "tools.health_cmd",
    "status": "tools.status_cmd",
    "registers": "tools.registers_cmd",
    "symbols": "tools.symbols_cmd",
    "certs": "tools.certs_cmd",
    "record": "tools.record_cmd",
    "payload": "tools.payload_cmd",
    "simulate": "tools.simulate_cmd",
    "compare": "tools.compare_cmd",
    "diagnose": "tools.diagnose_cmd",
    "plan": "tools.plan_cmd",
    "model": "tools.model_cmd",
    "hil": "tools.hil_cmd",
    "part": "tools.part_cmd",
    "modes": "tools.modes_cmd",
    "modal-map": "tools.modal_map_cmd",
    "plc-library": "tools.plc_library_cmd",
    "robot-programs": "tools.robot_programs_cmd",
}

EXIT_USER_ERROR = 2


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser with every subcommand, or only ``command``'s when it names one."""
    parser = argparse.ArgumentParser(
        prog="stiffcomp",
        description="Stiffness modelling and real-time deformation compensation for industrial robots.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    modules = [COMMANDS[command]] if command in COMMANDS else dict.fromkeys(COMMANDS.values())
    for name in modules:
        importlib.import_module(name).register(sub)
    return parser


def user_errors() -> tuple[type[BaseException], ...]:
    """The roots of the error trees that mean bad input, reported in one line without a traceback."""
    from hil.run import HilError
    from io_base.errors import PlcError
    from service.errors import ServiceError

    return (StiffnessError, ServiceError, PlcError, HilError)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(argv[0] if argv else None).parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except user_errors() as e:
        print(f"stiffcomp {args.command}: error: {e}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
