"""HTTPS for ``campaign gui --allow-remote``: the server's certificate and its fingerprint.

A server reachable from the network sends the access token, the password and
the campaign's data: never in plain HTTP. Either the operator gives a
certificate and its key (``--certfile``/``--keyfile``, PEM), or a self-signed
certificate is made at start (``cryptography``: an EC P-256 key, valid
:data:`SELF_SIGNED_DAYS` days, for the bound address, ``localhost`` and the
machine's name), kept only in memory. A browser cannot vouch for a self-signed
certificate: the SHA-256 fingerprint the command prints is what the user
compares with the one the browser shows before accepting it.
"""

from __future__ import annotations

import datetime
import hashlib
import ipaddress
import socket
import ssl
import tempfile
from dataclasses import dataclass
from pathlib import Path

from analysis.errors import InputError

#: validity of a self-signed certificate made at start (days)
SELF_SIGNED_DAYS = 30


@dataclass(frozen=True)
class ServerCertificate:
    """context: the server's TLS context (TLS 1.2 or later); fingerprint: SHA-256 of the
    certificate (DER), colon-separated hex as browsers show it; source: where it came
    from, for the start-up lines."""

    context: ssl.SSLContext
    fingerprint: str
    source: str


def fingerprint_of(der: bytes) -> str:
    """SHA-256 of a DER certificate as ``AB:CD:...`` (upper-case hex, colon-separated)."""
    digest = hashlib.sha256(der).hexdigest().upper()
    return ":".join(digest[i:i + 2] for i in range(0, len(digest), 2))


def _context() -> ssl.SSLContext:
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    return context


def load_certificate(certfile: Path, keyfile: Path) -> ServerCertificate:
    """The operator's certificate and key (PEM files); InputError naming the bad file."""
    for path, option in ((certfile, "--certfile"), (keyfile, "--keyfile")):
        if not Path(path).is_file():
            raise InputError("file not found", where=f"{option} {path}")
    try:
        text = Path(certfile).read_text(encoding="ascii")
        begin = text.index("-----BEGIN CERTIFICATE-----")
        end = text.index("-----END CERTIFICATE-----", begin) + len("-----END CERTIFICATE-----")
        der = ssl.PEM_cert_to_DER_cert(text[begin:end])
    except (UnicodeDecodeError, ValueError):
        raise InputError("not a PEM certificate (no BEGIN CERTIFICATE block)",
                         where=f"--certfile {certfile}") from None
    context = _context()
    try:
        context.load_cert_chain(certfile, keyfile)
    except ssl.SSLError as err:
        raise InputError(f"the key does not fit the certificate or is not a PEM key "
                         f"({err.reason or err})", where=f"--keyfile {keyfile}") from None
    return ServerCertificate(context, fingerprint_of(der), f"--certfile {certfile}")


def _names(host: str) -> list:
    """The subject alternative names of a certificate for a server bound to ``host``."""
    from cryptography import x509

    names: list = [x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]
    candidates = [host.strip("[]"), socket.gethostname()]
    for name in candidates:
        try:
            address = ipaddress.ip_address(name)
        except ValueError:
            if name and name != "localhost":
                names.append(x509.DNSName(name))
            continue
        if not address.is_unspecified and x509.IPAddress(address) not in names:
            names.append(x509.IPAddress(address))
    return names


def self_signed(host: str) -> ServerCertificate:
    """A fresh self-signed certificate for a server bound to ``host``, in memory only.

    ``ssl`` loads a key only from a file: key and certificate pass through a private
    temporary directory (mode 0700) that is removed before this returns.
    """
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "campaign gui"),
                      x509.NameAttribute(NameOID.ORGANIZATION_NAME, "robot-stiffness-campaign")])
    now = datetime.datetime.now(datetime.UTC)
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=SELF_SIGNED_DAYS))
            .add_extension(x509.SubjectAlternativeName(_names(host)), critical=False)
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .sign(key, hashes.SHA256()))
    context = _context()
    with tempfile.TemporaryDirectory(prefix="campaign-gui-tls-") as tmp:
        cert_file, key_file = Path(tmp) / "cert.pem", Path(tmp) / "key.pem"
        cert_file.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
        key_file.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                               serialization.PrivateFormat.PKCS8,
                                               serialization.NoEncryption()))
        context.load_cert_chain(cert_file, key_file)
    der = cert.public_bytes(serialization.Encoding.DER)
    return ServerCertificate(context, fingerprint_of(der),
                             f"self-signed, made at start, valid {SELF_SIGNED_DAYS} days")


def server_certificate(host: str, allow_remote: bool, certfile: Path | None,
                       keyfile: Path | None) -> ServerCertificate | None:
    """The certificate to serve with: the given files, else a self-signed one for remote
    access, else None (plain HTTP on loopback)."""
    if (certfile is None) != (keyfile is None):
        missing = "--keyfile" if keyfile is None else "--certfile"
        raise InputError(f"give both --certfile and --keyfile; {missing} is missing",
                         where=missing)
    if certfile is not None:
        return load_certificate(Path(certfile), Path(keyfile))
    if allow_remote:
        return self_signed(host)
    return None
