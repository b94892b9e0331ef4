"""``campaign gui``: the browser face (sensitivity explorer, runs) on a local web server."""

from __future__ import annotations

from pathlib import Path

import typer


def _announce(workspace: Path, url: str, cert, hardware: bool = False) -> None:
    """The start-up lines: what is served, the URL, the certificate to check, and whether
    acquisitions may run on hardware."""
    typer.echo(f"campaign gui: serving {workspace.resolve()}\nopen {url}")
    typer.echo("acquisitions: on hardware allowed (--hardware; each run asks its confirmation)"
               if hardware else "acquisitions: simulated lab only (start with --hardware to "
               "drive a real robot)")
    if cert is not None:
        typer.echo(f"TLS certificate ({cert.source}) SHA-256 fingerprint:\n"
                   f"  {cert.fingerprint}\n"
                   "(check that your browser shows this fingerprint before you accept it)")
    typer.echo("(Ctrl-C stops the server)")


def register(app: typer.Typer) -> None:
    @app.command("gui")
    def gui(
        workspace: Path = typer.Option(Path("."), help="Directory of plans, runs and "
                                       "analyses; the server reads and writes only there."),
        port: int = typer.Option(8765, help="TCP port (0: any free port)."),
        no_browser: bool = typer.Option(False, "--no-browser", help="Do not open a browser."),
        host: str = typer.Option("127.0.0.1", help="Address to bind; not loopback only with "
                                 "--allow-remote and --password."),
        allow_remote: bool = typer.Option(False, "--allow-remote",
                                          help="Remote access: a non-loopback --host, the "
                                          "password, HTTPS only."),
        password: str = typer.Option(None, help="Password of /login for remote use."),
        certfile: Path = typer.Option(None, "--certfile", help="TLS certificate (PEM) for "
                                      "HTTPS; with --allow-remote and no certificate, a "
                                      "self-signed one is made at start."),
        keyfile: Path = typer.Option(None, "--keyfile", help="Private key (PEM) of "
                                     "--certfile."),
        hardware: bool = typer.Option(False, "--hardware", help="Let the Acquire view run "
                                      "on a real robot (each run still after its "
                                      "confirmation, limits and dry run); without it, the "
                                      "simulated lab only."),
        scheduler: str = typer.Option(None, "--scheduler", help="Dask scheduler of the "
                                      "Placement view's search, tcp://HOST:PORT (default: a "
                                      "local cluster); a request cannot name another."),
        db: str = typer.Option(None, "--db", help="Fleet ledger of the Fleet view, where "
                               "the GUI's analyses are recorded (default: the "
                               "STIFFNESS_CAMPAIGN_DB environment variable)."),
    ) -> None:
        """Start the GUI on a local web server and print its URL with the access token.

        Every request needs the token (the URL sets a cookie); the server binds
        127.0.0.1 unless --host, --allow-remote and --password say otherwise.
        Remote access is HTTPS only: --certfile/--keyfile, or a self-signed
        certificate made at start whose SHA-256 fingerprint is printed.
        Ctrl-C stops it.
        """
        from campaign.web.security import new_token
        from campaign.web.server import GuiOptions, serve

        options = GuiOptions(workspace=workspace, host=host, port=port,
                             open_browser=not no_browser, allow_remote=allow_remote,
                             password=password, certfile=certfile, keyfile=keyfile,
                             hardware=hardware, scheduler=scheduler, ledger=db)
        serve(options, new_token(), lambda url, cert: _announce(workspace, url, cert, hardware))
