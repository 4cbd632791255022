"""Certificates and clients of the Modbus/TCP Security tests: a cell's CA with a server certificate and
clients of each role, and a CA of somebody else's, all made by `io_base.certs` (ECDSA keys: fast
to make; the RSA default is made by the CLI test)."""

from __future__ import annotations

import ssl
from pathlib import Path
from types import SimpleNamespace

from pymodbus.client import ModbusTcpClient, ModbusTlsClient

from io_base import certs
from io_base.tls import client_context

OUTSIDE = "127.0.0.2"       # a second loopback address: a client that is not in plc.writers


def cert_set(folder: Path) -> SimpleNamespace:
    """``ca``, ``server``, clients ``operator`` (role operator), ``viewer`` (role viewer), ``norole``,
    ``guest`` (a role no config lists), and ``foreign`` (role operator, signed by another CA)."""
    folder.mkdir(parents=True, exist_ok=True)
    ca = certs.make_ca(folder, key_type="ec")
    out = SimpleNamespace(folder=folder, ca=ca, server=certs.make_server(ca, folder, ["localhost", "127.0.0.1"],
                                                                         key_type="ec"))
    for name, role in (("operator", "operator"), ("viewer", "viewer"), ("norole", None), ("guest", "guest")):
        setattr(out, name, certs.make_client(ca, folder, name, role, key_type="ec"))
    other = folder / "other"
    other.mkdir(exist_ok=True)
    out.foreign = certs.make_client(certs.make_ca(other, "another CA", key_type="ec"), other, "foreign",
                                    "operator", key_type="ec")
    return out


def tls_settings(cs: SimpleNamespace, port: int, **more) -> dict:
    """The ``plc.tls`` section serving ``cs``."""
    return {"enabled": True, "port": port, "cert": str(cs.server.cert), "key": str(cs.server.key),
            "ca": str(cs.ca.cert)} | more


def tls_client(cs: SimpleNamespace, port: int, cert: certs.Issued | None, tls12: bool = False) -> ModbusTlsClient:
    """pymodbus' TLS client that verifies the server against the cell's CA and shows ``cert`` (None:
    none). pymodbus' sync client sends no server name, so the name check is off; the chain is checked.
    ``tls12``: at most TLS 1.2, where the server's verdict on the client comes within the handshake."""
    ctx = client_context(str(cs.ca.cert), cert and str(cert.cert), cert and str(cert.key), check_hostname=False)
    if tls12:
        ctx.maximum_version = ssl.TLSVersion.TLSv1_2
    return ModbusTlsClient("127.0.0.1", port=port, sslctx=ctx, timeout=3, retries=0)


def outside_client(port: int) -> ModbusTcpClient:
    """A plain client whose socket is bound to `OUTSIDE`."""
    return ModbusTcpClient("127.0.0.1", port=port, source_address=(OUTSIDE, 0), timeout=3, retries=0)
