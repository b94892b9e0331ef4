"""``campaign gui``: the browser face (sensitivity explorer, runs) on a local web server."""

from __future__ import annotations

from pathlib import Path

import typer


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
                                          help="Allow a non-loopback --host."),
        password: str = typer.Option(None, help="Password of /login for remote use."),
    ) -> None:
        """Start the GUI on a local web server and print its URL with the access token.

        Every request needs the token (the URL sets a cookie); the server binds
        127.0.0.1 unless --host, --allow-remote and --password say otherwise.
        Ctrl-C stops it.
        """
        from campaign.web.security import new_token
        from campaign.web.server import GuiOptions, serve

        options = GuiOptions(workspace=workspace, host=host, port=port,
                             open_browser=not no_browser, allow_remote=allow_remote,
                             password=password)
        serve(options, new_token(),
              lambda url: typer.echo(f"campaign gui: serving {workspace.resolve()}\n"
                                     f"open {url}\n(Ctrl-C stops the server)"))
