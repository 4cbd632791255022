"""Modbus/TCP Security on the server side: the TLS context, the client's role, and certificates
replaced on disk taken up without a restart.

Modbus/TCP Security (Modbus Organization, 2018) is the Modbus TCP frame inside TLS 1.2 or later, on port
802, with X.509 certificates on both sides (mutual authentication). A client certificate may name the
client's role in an extension (OID 1.3.6.1.4.1.50316.802.1, an ASN.1 UTF8String); the server decides from
the role what the client may do, and answers a request the role does not allow with exception 01
(illegal function). Here a role maps to ``none``, ``read`` or ``write`` (`settings.TlsSettings.roles`).

`ServerTls.context` is asked for the context at every new connection. When the certificate, key or CA
file changed on disk since the last look, it builds a new context from them first; a set that does not
load is logged and the previous context kept, so a half-copied rotation never stops the service. A
rotated certificate therefore serves from the next connection on, and connections already open keep
their session (docs/security.md).
"""

from __future__ import annotations

import logging
import os
import ssl

from .errors import PlcError
from .settings import Access, TlsSettings

log = logging.getLogger("stiffcomp.modbus")

ROLE_OID = "1.3.6.1.4.1.50316.802.1"        # Modbus/TCP Security's role extension


def server_context(cert: str, key: str, ca: str) -> ssl.SSLContext:
    """A server context that requires a client certificate signed by ``ca`` (TLS 1.2 or later, as
    Modbus/TCP Security requires); PlcError names the key and file that do not load."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    ctx.verify_mode = ssl.CERT_REQUIRED
    try:
        ctx.load_cert_chain(cert, key)
    except (OSError, ssl.SSLError) as e:
        raise PlcError(f"plc.tls.cert = {cert}, plc.tls.key = {key}: not a PEM certificate and its "
                       f"unencrypted private key ({_why(e)})") from e
    try:
        ctx.load_verify_locations(cafile=ca)
    except (OSError, ssl.SSLError) as e:
        raise PlcError(f"plc.tls.ca = {ca}: not a PEM CA certificate ({_why(e)})") from e
    return ctx


def client_context(ca: str, cert: str | None = None, key: str | None = None,
                   check_hostname: bool = True) -> ssl.SSLContext:
    """A client context that trusts servers signed by ``ca`` and shows ``cert`` (with ``key``).

    pymodbus' synchronous `ModbusTlsClient` does not send the server's name, so with it pass
    ``check_hostname=False``: the server's certificate chain is verified all the same.
    """
    ctx = ssl.create_default_context(cafile=ca)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    ctx.check_hostname = check_hostname
    if cert is not None:
        ctx.load_cert_chain(cert, key)
    return ctx


def role_of(der: bytes) -> str | None:
    """The Modbus role a certificate (DER) names, or None when it names none or it cannot be read."""
    # the declarative ASN.1 API (decode_der) is documented since cryptography 47, pyproject.toml's floor
    from cryptography import x509
    from cryptography.hazmat.asn1 import decode_der

    try:
        ext = x509.load_der_x509_certificate(der).extensions.get_extension_for_oid(x509.ObjectIdentifier(ROLE_OID))
        return decode_der(str, ext.value.value)
    except (x509.ExtensionNotFound, ValueError):
        return None


def handshake_failure(e: BaseException) -> str:
    """Why a handshake failed, in a few words (a metric label: a small fixed set)."""
    reason = str(getattr(e, "reason", "") or "").upper()
    if reason == "PEER_DID_NOT_RETURN_A_CERTIFICATE":
        return "no client certificate"
    if reason == "CERTIFICATE_VERIFY_FAILED":
        return "client certificate not trusted"
    if isinstance(e, ssl.SSLError) and reason in ("WRONG_VERSION_NUMBER", "HTTP_REQUEST", "UNEXPECTED_RECORD"):
        return "not TLS"
    if isinstance(e, ssl.SSLError):
        return "TLS handshake failed"
    if isinstance(e, ConnectionAbortedError) and "longer than" in str(e):
        return "TLS handshake timed out"
    return "closed during the TLS handshake"


def _why(e: BaseException) -> str:
    verify = getattr(e, "verify_message", None)
    return f"{e.strerror or e}: {e.filename}" if isinstance(e, OSError) and e.filename else str(verify or e)


class ServerTls:
    """The server's TLS context, rebuilt when its files change, and what a client's certificate allows.

    Parameters
    ----------
    settings : `settings.TlsSettings` (enabled, with absolute paths)

    Raises
    ------
    PlcError
        When the files do not load at start-up (naming the key and file).
    """

    def __init__(self, settings: TlsSettings):
        self.settings = settings
        self.files = (settings.cert, settings.key, settings.ca)
        self._stamp = _stamp(self.files)
        self._context = server_context(*self.files)

    def context(self) -> ssl.SSLContext:
        """The context for a new connection (the files' new contents when they changed and load)."""
        stamp = _stamp(self.files)
        if stamp != self._stamp:
            self._stamp = stamp
            try:
                self._context = server_context(*self.files)
            except PlcError as e:
                log.warning("plc.tls: the certificate files changed but do not load; new connections keep the "
                            "previous certificates until they do: %s", e)
            else:
                log.info("plc.tls: new certificates loaded from %s", ", ".join(self.files))
        return self._context

    def access(self, ssl_object: ssl.SSLObject | None) -> tuple[Access, str | None]:
        """What the client of an established connection may do, and the role its certificate names."""
        der = ssl_object.getpeercert(binary_form=True) if ssl_object is not None else None
        if not der:
            return "none", None
        role = role_of(der)
        return self.settings.access(role), role


def _stamp(files) -> tuple:
    """What tells a changed file: its modification time, size and inode (None when it is missing)."""
    out = []
    for f in files:
        try:
            st = os.stat(f)
            out.append((st.st_mtime_ns, st.st_size, st.st_ino))
        except OSError:
            out.append(None)
    return tuple(out)
