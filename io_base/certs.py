"""Certificates for commissioning Modbus/TCP Security: a CA of the cell, the server's certificate and
client certificates with a Modbus role (`stiffcomp certs`, docs/security.md).

Made with the `cryptography` package: RSA 2048 keys by default (Modbus/TCP Security's mandatory cipher
suites use RSA, so every conforming client can talk to it), ECDSA P-256 on request. The CA may sign
only end-entity certificates (path length 0); the server certificate names its hosts (DNS names and
IP addresses) for the client's name check and may only serve (extended key usage serverAuth); a client
certificate may only be a client (clientAuth) and carries its role in the Modbus role extension
(`tls.ROLE_OID`, a UTF8String). Keys are written unencrypted with mode 0600: the service starts
without a person typing a pass phrase, so the file's permissions are what protect it.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
from dataclasses import dataclass
from pathlib import Path

from .errors import PlcError
from .tls import ROLE_OID

KEY_TYPES = ("rsa", "ec")
CA_DAYS = 3650          # a new CA's validity: the longest a certificate it signs is made for


@dataclass(frozen=True)
class Issued:
    """A certificate and its key as written: ``cert`` and ``key`` paths."""

    cert: Path
    key: Path


def _new_key(key_type: str):
    from cryptography.hazmat.primitives.asymmetric import ec, rsa

    if key_type == "ec":
        return ec.generate_private_key(ec.SECP256R1())
    return rsa.generate_private_key(public_exponent=65537, key_size=2048)


def _write(path: Path, data: bytes, private: bool) -> None:
    """Write ``data`` to ``path`` whole (a temporary file renamed over it), 0600 when ``private``."""
    tmp = path.with_name(path.name + ".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600 if private else 0o644)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


def _save(folder: Path, name: str, cert, key) -> Issued:
    from cryptography.hazmat.primitives import serialization

    out = Issued(folder / f"{name}.pem", folder / f"{name}.key")
    _write(out.key, key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                      serialization.NoEncryption()), private=True)
    _write(out.cert, cert.public_bytes(serialization.Encoding.PEM), private=False)
    return out


def _builder(subject: str, issuer, public_key, days: float):
    from cryptography import x509
    from cryptography.x509.oid import NameOID

    now = dt.datetime.now(dt.UTC)
    return (x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, subject)]))
            .issuer_name(issuer)
            .public_key(public_key)
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))        # a peer whose clock lags a little
            .not_valid_after(now + dt.timedelta(days=days))
            .add_extension(x509.SubjectKeyIdentifier.from_public_key(public_key), critical=False))


def make_ca(folder: Path, name: str = "stiffcomp cell CA", days: float = CA_DAYS, key_type: str = "rsa") -> Issued:
    """A self-signed CA (``ca.pem``, ``ca.key``) in ``folder``."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.x509.oid import NameOID

    key = _new_key(key_type)
    issuer = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    cert = (_builder(name, issuer, key.public_key(), days)
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .add_extension(x509.KeyUsage(digital_signature=False, content_commitment=False, key_encipherment=False,
                                         data_encipherment=False, key_agreement=False, key_cert_sign=True,
                                         crl_sign=True, encipher_only=False, decipher_only=False), critical=True)
            .sign(key, hashes.SHA256()))
    return _save(folder, "ca", cert, key)


def existing_ca(folder: Path) -> Issued | None:
    """The CA already in ``folder`` (``ca.pem`` with ``ca.key``), or None; PlcError when half of it is there."""
    ca = Issued(folder / "ca.pem", folder / "ca.key")
    if ca.cert.exists() != ca.key.exists():
        missing, there = (ca.key, ca.cert) if ca.cert.exists() else (ca.cert, ca.key)
        raise PlcError(f"{missing} is missing beside {there}: a CA needs both to sign; move {there} away to "
                       "start a new CA (every certificate it signed must then be made again)")
    return ca if ca.cert.exists() else None


def _issue(ca: Issued, folder: Path, name: str, subject: str, days: float, key_type: str, usage, extra) -> Issued:
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization

    ca_cert = x509.load_pem_x509_certificate(ca.cert.read_bytes())
    ca_key = serialization.load_pem_private_key(ca.key.read_bytes(), password=None)
    key = _new_key(key_type)
    rsa_key = key_type == "rsa"
    builder = (_builder(subject, ca_cert.subject, key.public_key(), days)
               .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
               .add_extension(x509.KeyUsage(digital_signature=True, content_commitment=False,
                                            key_encipherment=rsa_key, data_encipherment=False,
                                            key_agreement=not rsa_key, key_cert_sign=False, crl_sign=False,
                                            encipher_only=False, decipher_only=False), critical=True)
               .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
               .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()),
                              critical=False))
    for ext in extra:
        builder = builder.add_extension(ext, critical=False)
    return _save(folder, name, builder.sign(ca_key, hashes.SHA256()), key)


def make_server(ca: Issued, folder: Path, hosts: list[str], days: float = 825, key_type: str = "rsa") -> Issued:
    """The server's certificate (``server.pem``, ``server.key``) for ``hosts``: names and IP addresses."""
    from cryptography import x509
    from cryptography.x509.oid import ExtendedKeyUsageOID

    names = []
    for h in hosts:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(h)))
        except ValueError:
            names.append(x509.DNSName(h))
    return _issue(ca, folder, "server", hosts[0], days, key_type, ExtendedKeyUsageOID.SERVER_AUTH,
                  [x509.SubjectAlternativeName(names)])


def make_client(ca: Issued, folder: Path, name: str, role: str | None, days: float = 825,
                key_type: str = "rsa") -> Issued:
    """A client certificate (``NAME.pem``, ``NAME.key``) whose Modbus role extension names ``role``
    (None: no role extension)."""
    from cryptography import x509
    from cryptography.hazmat.asn1 import encode_der
    from cryptography.x509.oid import ExtendedKeyUsageOID

    extra = [] if role is None else [x509.UnrecognizedExtension(x509.ObjectIdentifier(ROLE_OID), encode_der(role))]
    return _issue(ca, folder, name, name, days, key_type, ExtendedKeyUsageOID.CLIENT_AUTH, extra)
