"""Meshcat without exposure: an offline window for the self-contained replay (no server, no socket), and a live
server that listens on 127.0.0.1 only.

meshcat's own server (``meshcat.Visualizer()``) starts a tornado web server on every interface (0.0.0.0 and
[::]) although it prints a 127.0.0.1 URL. :func:`offline_visualizer` keeps the scene tree in this process with
meshcat's own bridge code (so ``static_html()`` is what the server would have returned); :func:`local_visualizer`
starts the server subprocess with its web server bound to ``host`` (default 127.0.0.1).

``python -m robofdi.viz.meshcat_local [--host HOST]`` runs that server (what :func:`local_visualizer` starts).
"""
from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys

import meshcat

__all__ = ["offline_visualizer", "local_visualizer", "LOCALHOST"]

LOCALHOST = "127.0.0.1"


class _Reply:
    """Where meshcat's bridge code sends its answer (a zmq socket in the server)."""

    data = b""

    def send(self, data: bytes) -> None:
        self.data = data

    def close(self, linger=0) -> None:
        pass


class _OfflineWindow:
    """A meshcat window whose scene tree lives in this process; ``get_scene()`` gives the static HTML."""

    def __init__(self):
        from meshcat.servers.zmqserver import SceneTree

        self.tree = SceneTree()
        self.websocket_pool: set = set()
        self.zmq_socket = _Reply()
        self.server_proc = None
        self.web_url = None

    def forward_to_websockets(self, frames) -> None:     # no browser is connected
        pass

    def _handle(self, frames) -> bytes:
        from meshcat.servers.zmqserver import ZMQWebSocketBridge

        ZMQWebSocketBridge.handle_zmq(self, frames)       # meshcat's own tree update / HTML export
        return self.zmq_socket.data

    def send(self, command) -> None:
        from meshcat.visualizer import umsgpack

        data = command.lower()
        self._handle([data["type"].encode("utf-8"), data["path"].encode("utf-8"), umsgpack.packb(data)])

    def get_scene(self) -> str:
        return self._handle([b"get_scene"]).decode("utf-8")

    def open(self):
        return self


def offline_visualizer() -> meshcat.Visualizer:
    """A Visualizer for building a scene and exporting it with ``static_html()``: starts no server."""
    return meshcat.Visualizer(window=_OfflineWindow())


def local_visualizer(host: str = LOCALHOST) -> meshcat.Visualizer:
    """A Visualizer on a meshcat server subprocess whose web server and zmq socket listen on ``host`` only."""
    from meshcat.servers.zmqserver import match_web_url, match_zmq_url
    from meshcat.visualizer import ViewerWindow

    proc = subprocess.Popen([sys.executable, "-u", "-m", "robofdi.viz.meshcat_local", "--host", host],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=dict(os.environ),
                            start_new_session=True)
    line = ""
    while "zmq_url" not in line:
        line = proc.stdout.readline().decode("utf-8").strip()
        if proc.poll() is not None:
            err = proc.stderr.read().decode("utf-8", "replace").strip().splitlines()
            raise RuntimeError(f"the meshcat server exited with code {proc.returncode}: {err[-1] if err else ''}")
    zmq_url = match_zmq_url(line)
    match_web_url(proc.stdout.readline().decode("utf-8").strip())
    with contextlib.redirect_stdout(io.StringIO()):
        window = ViewerWindow(zmq_url=zmq_url, start_server=False, server_args=[])
    window.server_proc = proc
    return meshcat.Visualizer(window=window)


def _serve(host: str) -> None:
    """meshcat's server with its tornado web server bound to ``host`` (meshcat passes no address: every
    interface)."""
    import functools

    import tornado.web
    from meshcat.servers import zmqserver

    listen = tornado.web.Application.listen
    tornado.web.Application.listen = functools.partialmethod(listen, address=host)
    bridge = zmqserver.ZMQWebSocketBridge(host=host)
    print(f"zmq_url={bridge.zmq_url}")
    print(f"web_url={bridge.web_url}")
    with contextlib.suppress(KeyboardInterrupt):
        bridge.run()


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description="meshcat's server, listening on one address only")
    parser.add_argument("--host", default=LOCALHOST)
    _serve(parser.parse_args().host)
