"""Remote access to ``campaign gui`` is HTTPS only: a real TLS client, all on loopback.

``--allow-remote`` is remote mode whatever the address (a loopback address may be
forwarded), so the tests bind 127.0.0.1 (and 127.0.0.2) with it: the server must
speak TLS with the certificate whose SHA-256 fingerprint it prints, keep the token
and the password, mark its cookie Secure, and answer no plain HTTP.
"""

from __future__ import annotations

import datetime
import http.client
import ipaddress
import socket
import ssl
import subprocess
import sys
import threading
import time

import pytest

from analysis.errors import InputError

pytest.importorskip("cryptography", reason="cryptography is not installed (pip install "
                    "cryptography)")
PASSWORD = "a-long-password"
TOKEN = "t" * 43


def _peer_der(host: str, port: int) -> bytes:
    """The server's certificate (DER), taken without trusting it."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.check_hostname = False
    ctx.verify_mode = ssl.CERT_NONE
    with socket.create_connection((host, port), timeout=10) as raw, \
            ctx.wrap_socket(raw, server_hostname=host) as tls:
        return tls.getpeercert(binary_form=True)


def _trusting(der: bytes) -> ssl.SSLContext:
    """A verifying client context that trusts exactly this certificate (host name checked)."""
    return ssl.create_default_context(cadata=ssl.DER_cert_to_PEM_cert(der))


def _get(host, port, path, ctx, headers=None):
    conn = http.client.HTTPSConnection(host, port, context=ctx, timeout=10)
    try:
        conn.request("GET", path, headers=headers or {})
        r = conn.getresponse()
        return r.status, r.read(), r.headers
    finally:
        conn.close()


class Running:
    """The GUI server of ``options`` in a thread of this process."""

    def __init__(self, options):
        from campaign.web.server import prepare

        self.prepared = prepare(options, TOKEN)
        self.port = self.prepared.sock.getsockname()[1]
        server = self.prepared.server
        self.thread = threading.Thread(target=server.run,
                                       kwargs={"sockets": [self.prepared.sock]}, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 20
        while not server.started and time.monotonic() < deadline:
            time.sleep(0.05)
        assert server.started

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.prepared.server.should_exit = True
        self.thread.join(10)
        self.prepared.sock.close()


def _options(tmp_path, **kw):
    from campaign.web.server import GuiOptions

    return GuiOptions(workspace=tmp_path, port=0, open_browser=False, **kw)


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.2"])
def test_remote_mode_is_https_with_the_printed_fingerprint(tmp_path, host):
    from campaign.web.tls import fingerprint_of

    try:
        running = Running(_options(tmp_path, host=host, allow_remote=True, password=PASSWORD))
    except InputError as err:  # 127.0.0.2 is loopback on Linux, not everywhere
        pytest.skip(f"cannot bind {host}: {err}")
    with running:
        der = _peer_der(host, running.port)
        assert fingerprint_of(der) == running.prepared.cert.fingerprint
        assert len(running.prepared.cert.fingerprint) == 32 * 3 - 1
        ctx = _trusting(der)  # verifies the chain and that the name fits the address
        status, body, _ = _get(host, running.port, "/api/runs", ctx,
                               {"Authorization": f"token {TOKEN}"})
        assert (status, body) == (200, b"[]")
        assert _get(host, running.port, "/api/runs", ctx)[0] == 401
        conn = http.client.HTTPSConnection(host, running.port, context=ctx, timeout=10)
        conn.request("POST", "/login", body=f"password={PASSWORD}",
                     headers={"Content-Type": "application/x-www-form-urlencoded"})
        r = conn.getresponse()
        cookie = r.headers.get("set-cookie", "")
        conn.close()
        assert r.status == 303 and "campaign_gui_token=" in cookie
        assert "secure" in cookie.lower() and "httponly" in cookie.lower()
        # plain HTTP gets no answer from the TLS port
        plain = http.client.HTTPConnection(host, running.port, timeout=10)
        with pytest.raises((http.client.HTTPException, OSError)):
            plain.request("GET", f"/api/runs?token={TOKEN}")
            plain.getresponse()
        plain.close()


def _write_certificate(tmp_path):
    """A certificate for 127.0.0.1 and its key, as an operator would give them (PEM)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "operator's cert")])
    now = datetime.datetime.now(datetime.UTC)
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName(
                [x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]), critical=False)
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .sign(key, hashes.SHA256()))
    certfile, keyfile = tmp_path / "cert.pem", tmp_path / "key.pem"
    certfile.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    keyfile.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                          serialization.PrivateFormat.PKCS8,
                                          serialization.NoEncryption()))
    return certfile, keyfile, cert.public_bytes(serialization.Encoding.DER)


def test_given_certificate_is_served(tmp_path):
    from campaign.web.tls import fingerprint_of

    ws = tmp_path / "ws"
    ws.mkdir()
    certfile, keyfile, der = _write_certificate(tmp_path)
    with Running(_options(ws, certfile=certfile, keyfile=keyfile)) as running:
        assert running.prepared.cert.fingerprint == fingerprint_of(der)
        assert _peer_der("127.0.0.1", running.port) == der
        ctx = ssl.create_default_context(cafile=str(certfile))
        status, body, _ = _get("127.0.0.1", running.port, "/api/runs", ctx,
                               {"Authorization": f"token {TOKEN}"})
        assert (status, body) == (200, b"[]")


def test_cli_prints_https_url_and_fingerprint(tmp_path):
    """The command as a user runs it: ``--allow-remote`` prints an https URL and the
    fingerprint; a TLS client sees that certificate."""
    from campaign.web.tls import fingerprint_of

    proc = subprocess.Popen([sys.executable, "-m", "campaign", "gui", "--workspace",
                             str(tmp_path), "--port", "0", "--no-browser", "--allow-remote",
                             "--password", PASSWORD],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        lines = []
        for line in proc.stdout:
            lines.append(line.rstrip("\n"))
            if line.startswith("(Ctrl-C"):
                break
        url = next(s.split()[1] for s in lines if s.startswith("open "))
        assert url.startswith("https://127.0.0.1:")
        printed = lines[lines.index(next(s for s in lines if "SHA-256 fingerprint" in s)) + 1]
        port = int(url.split(":")[2].split("/")[0])
        der = _peer_der("127.0.0.1", port)
        assert printed.strip() == fingerprint_of(der)
        token = url.split("?token=")[1]
        status, body, _ = _get("127.0.0.1", port, "/api/runs", _trusting(der),
                               {"Authorization": f"token {token}"})
        assert (status, body) == (200, b"[]")
    finally:
        proc.terminate()
        proc.wait(10)


@pytest.mark.parametrize("args,word", [
    (["--certfile", "{tmp}/cert.pem"], "--keyfile"),
    (["--certfile", "{tmp}/bad.pem", "--keyfile", "{tmp}/bad.pem"], "not a PEM certificate"),
    (["--certfile", "{tmp}/cert.pem", "--keyfile", "{tmp}/other.pem"], "--keyfile"),
    (["--allow-remote"], "--password"),
])
def test_tls_options_refused_with_one_line(tmp_path, args, word):
    certfile, keyfile, _ = _write_certificate(tmp_path)
    other = tmp_path / "other"
    other.mkdir()
    _write_certificate(other)
    (other / "key.pem").rename(tmp_path / "other.pem")  # a key of another certificate
    (tmp_path / "bad.pem").write_text("not a certificate\n")
    args = [a.format(tmp=tmp_path) for a in args]
    r = subprocess.run([sys.executable, "-m", "campaign", "gui", "--no-browser", "--port", "0",
                        "--workspace", str(tmp_path), *args],
                       capture_output=True, text=True, timeout=60)
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert len(errors) == 1 and word in errors[0], r.stderr


def test_the_page_works_over_https(tmp_path, browser):
    """Chromium opens the https URL (the self-signed certificate accepted, as a user does
    after comparing the fingerprint): the token becomes a Secure cookie, the page's own
    requests (GET /api/session, POST with the CSRF header) run over TLS."""
    with Running(_options(tmp_path, allow_remote=True, password=PASSWORD)) as running:
        context = browser.new_context(ignore_https_errors=True)
        try:
            page = context.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(f"https://127.0.0.1:{running.port}/?token={TOKEN}")
            page.wait_for_selector("#row-k6", timeout=30_000)
            assert page.url.startswith("https://127.0.0.1:") and "token=" not in page.url
            cookie = next(c for c in context.cookies() if c["name"] == "campaign_gui_token")
            assert cookie["secure"] and cookie["httpOnly"] and cookie["value"] == TOKEN
            median = page.locator("#row-k6 td.median").inner_text()
            assert any(ch.isdigit() for ch in median), median  # the POST's answer is shown
            assert not errors, errors
        finally:
            context.close()
