"""`stiffcomp certs`: a CA, the server's certificate and client certificates for Modbus/TCP Security.

For commissioning (docs/security.md): the CA in DIR is made once and then reused, so clients added
later are signed by the same CA; the server's certificate is made when DIR has none or ``--host`` is
given; each ``--client NAME[:ROLE]`` makes NAME.pem and NAME.key with the Modbus role ROLE (default
operator). It prints the ``plc.tls`` lines for the service config, and with ``--json`` the same as data.
"""

from __future__ import annotations

import json
import re
import socket
from pathlib import Path

from plc_interface.errors import PlcError

NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


def register(sub) -> None:
    p = sub.add_parser("certs", help="make a CA, a server certificate and client certificates for Modbus/TCP "
                                     "Security (commissioning)")
    p.add_argument("folder", metavar="DIR", help="where the files go (the CA in it is reused)")
    p.add_argument("--host", action="append", default=None, metavar="NAME_OR_IP",
                   help="a name or address clients reach the service by; (re)makes the server certificate "
                        "(repeat it; default when DIR has none: localhost, 127.0.0.1 and this machine's name)")
    p.add_argument("--client", action="append", default=[], metavar="NAME[:ROLE]",
                   help="a client certificate NAME.pem with the Modbus role ROLE (default operator; "
                        "plc.tls.roles says what each role may do); repeat it")
    p.add_argument("--days", type=float, default=825, help="validity of the server and client certificates")
    p.add_argument("--key-type", choices=("rsa", "ec"), default="rsa",
                   help="rsa (2048 bit, what every Modbus/TCP Security client supports) or ec (P-256)")
    p.add_argument("--json", action="store_true", help="print what was made, and the config, as JSON")
    p.set_defaults(func=run)


def _client(spec: str) -> tuple[str, str]:
    name, _, role = spec.partition(":")
    if not NAME.fullmatch(name) or name in ("ca", "server"):
        raise PlcError(f"--client {spec}: NAME must be letters, digits, '.', '_' or '-', and not ca or server")
    return name, role or "operator"


def run(args) -> int:
    from plc_interface import certs

    folder = Path(args.folder)
    clients = [_client(c) for c in args.client]
    folder.mkdir(parents=True, exist_ok=True)
    made: dict = {"folder": str(folder), "clients": []}
    ca = certs.existing_ca(folder)
    made["ca"] = {"cert": str(folder / "ca.pem"), "new": ca is None}
    if ca is None:
        ca = certs.make_ca(folder, key_type=args.key_type)
    if args.host or not (folder / "server.pem").exists():
        hosts = args.host or ["localhost", "127.0.0.1", socket.gethostname()]
        server = certs.make_server(ca, folder, list(dict.fromkeys(hosts)), args.days, args.key_type)
        made["server"] = {"cert": str(server.cert), "key": str(server.key), "hosts": hosts}
    for name, role in clients:
        c = certs.make_client(ca, folder, name, role, args.days, args.key_type)
        made["clients"].append({"name": name, "role": role, "cert": str(c.cert), "key": str(c.key)})
    tls = {"enabled": True, "cert": str((folder / "server.pem").resolve()),
           "key": str((folder / "server.key").resolve()), "ca": str((folder / "ca.pem").resolve())}
    made["config"] = {"plc": {"tls": tls}}
    made["next"] = ("give each client its NAME.pem and NAME.key, and ca.pem to verify the server; with the "
                    "tls lines in the service config, restart it (docs/security.md)")
    if args.json:
        print(json.dumps(made, indent=2))
        return 0
    print(f"CA: {made['ca']['cert']} ({'new' if made['ca']['new'] else 'kept'}; ca.key signs: keep it off the cell)")
    if "server" in made:
        print(f"server: {made['server']['cert']} for {', '.join(made['server']['hosts'])}")
    for c in made["clients"]:
        print(f"client {c['name']} (role {c['role']}): {c['cert']}, {c['key']}")
    print("\nin the service config (docs/security.md):\nplc:\n  tls:")
    for k, v in tls.items():
        print(f"    {k}: {json.dumps(v)}")
    print(f"\n{made['next']}")
    return 0
