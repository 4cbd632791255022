"""`stiffcomp certs`: a CA, the server's certificate and client certificates for Modbus/TCP Security.

For commissioning (docs/security.md): the CA in DIR is made once and then reused, so clients added
later are signed by the same CA; the server's certificate is made when DIR has none or ``--host`` is
given; each ``--client NAME[:ROLE]`` makes NAME.pem and NAME.key with the Modbus role ROLE (default
operator). It prints the ``plc.tls`` lines for a service config beside DIR (paths relative to the config's
folder, as the service reads them, so they also hold in a container that mounts that folder), and with
``--json`` the same as data.
"""

from __future__ import annotations

import json
import re
import socket
from pathlib import Path

from io_base.errors import PlcError

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
    p.add_argument("--days", type=float, default=825, help="validity of the server and client certificates, "
                   "1 to the CA's 3650 days")
    p.add_argument("--key-type", choices=("rsa", "ec"), default="rsa",
                   help="rsa (2048 bit, what every Modbus/TCP Security client supports) or ec (P-256)")
    p.add_argument("--json", action="store_true", help="print what was made, and the config, as JSON")
    p.set_defaults(func=run)


def _client(spec: str) -> tuple[str, str]:
    name, colon, role = spec.partition(":")
    if not NAME.fullmatch(name) or name in ("ca", "server"):
        raise PlcError(f"--client {spec}: NAME must be letters, digits, '.', '_' or '-', and not ca or server")
    if colon and (not role.strip() or ":" in role):
        raise PlcError(f"--client {spec}: the ROLE after NAME: must not be empty or hold ':' (e.g. plc:operator; "
                       "without :ROLE the role is operator)")
    return name, role or "operator"


def checked(args) -> tuple[Path, list[str] | None, list[tuple[str, str]]]:
    """DIR, the hosts and the clients, every option checked before anything is written; PlcError or
    ConfigError naming the option otherwise."""
    from io_base.certs import CA_DAYS

    from .common import check_number

    check_number("--days", args.days, "days the certificates are valid; the CA's own are "
                 f"{CA_DAYS}", at_least=1, at_most=CA_DAYS)
    folder = Path(args.folder)
    if folder.exists() and not folder.is_dir():
        raise PlcError(f"DIR {folder}: is a file, not a folder (the certificates go into a folder)")
    for host in args.host or []:
        if not host.strip():
            raise PlcError(f"--host {host!r}: empty; name a host name or an IP address clients reach the service by")
    clients = [_client(c) for c in args.client]
    names = [n for n, _ in clients]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise PlcError(f"--client {twice[0]}: given twice (one certificate per NAME)")
    return folder, args.host, clients


def run(args) -> int:
    from io_base import certs

    folder, hosts, clients = checked(args)
    folder.mkdir(parents=True, exist_ok=True)
    made: dict = {"folder": str(folder), "clients": []}
    ca = certs.existing_ca(folder)
    made["ca"] = {"cert": str(folder / "ca.pem"), "new": ca is None}
    if ca is None:
        ca = certs.make_ca(folder, key_type=args.key_type)
    if hosts or not (folder / "server.pem").exists():
        hosts = hosts or ["localhost", "127.0.0.1", socket.gethostname()]
        replaced = (folder / "server.pem").exists()
        server = certs.make_server(ca, folder, list(dict.fromkeys(hosts)), args.days, args.key_type)
        made["server"] = {"cert": str(server.cert), "key": str(server.key), "hosts": hosts, "replaced": replaced}
    for name, role in clients:
        replaced = (folder / f"{name}.pem").exists()
        c = certs.make_client(ca, folder, name, role, args.days, args.key_type)
        made["clients"].append({"name": name, "role": role, "cert": str(c.cert), "key": str(c.key),
                                "replaced": replaced})
    # relative to a config beside DIR, as the service reads them: the same lines hold on this machine and
    # in a container that mounts the config's folder (/etc/stiffcomp), where a path of this machine does not
    beside = folder.resolve().parent
    tls = {"enabled": True, **{k: (Path(folder.resolve().name) / f).as_posix()
                               for k, f in (("cert", "server.pem"), ("key", "server.key"), ("ca", "ca.pem"))}}
    made["config"] = {"plc": {"tls": tls}}
    made["config_folder"] = str(beside)
    made["next"] = ("give each client its NAME.pem and NAME.key, and ca.pem to verify the server; with the "
                    "tls lines in the service config, restart it (docs/security.md)")
    if args.json:
        print(json.dumps(made, indent=2))
        return 0
    report(made, tls)
    return 0


REPLACED = " (replaced the one that was there: its holder needs this one)"


def report(made: dict, tls: dict) -> None:
    """What was made, and the config's lines, as text."""
    print(f"CA: {made['ca']['cert']} ({'new' if made['ca']['new'] else 'kept'}; ca.key signs: keep it off the cell)")
    if "server" in made:
        s = made["server"]
        print(f"server: {s['cert']} for {', '.join(s['hosts'])}{REPLACED if s['replaced'] else ''}")
    for c in made["clients"]:
        print(f"client {c['name']} (role {c['role']}): {c['cert']}, {c['key']}{REPLACED if c['replaced'] else ''}")
    print(f"\nin a service config in {made['config_folder']}/ (paths relative to the config's folder, so they hold "
          "where that folder is mounted, /etc/stiffcomp in the image; a config elsewhere names them relative to "
          "its own folder; docs/security.md):\nplc:\n  tls:")
    for k, v in tls.items():
        print(f"    {k}: {json.dumps(v)}")
    print(f"\n{made['next']}")
