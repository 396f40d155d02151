"""An offline meshcat viewer: the scene is recorded in this process, for writing files.

:func:`offline_visualizer` returns a visualizer whose window is a :class:`_SceneRecorder`
instead of a zmq connection; its ``static_html()`` is byte for byte the page a meshcat
server would return for the same commands, with no server, port or subprocess.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

__all__ = ["offline_visualizer"]

# The page meshcat 0.3.2's server returns for "get_scene" (zmqserver.py), verbatim, so that
# an offline scene gives byte for byte the file the server would.
_STATIC_HTML = """
                <!DOCTYPE html>
                <html>
                    <head> <meta charset=utf-8> <title>MeshCat</title> </head>
                    <body>
                        <div id="meshcat-pane">
                        </div>
                        <script>
                            {mainminjs}
                        </script>
                        <script>
                            var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
                            {commands}
                        </script>
                         <style>
                            body {{margin: 0; }}
                            #meshcat-pane {{
                                width: 100vw;
                                height: 100vh;
                                overflow: hidden;
                            }}
                        </style>
                        <script id="embedded-json"></script>
                    </body>
                </html>
            """  # noqa: E501


class _SceneRecorder:
    """Stands in for meshcat's ``ViewerWindow``: keeps the scene tree in this process.

    It stores every command exactly as meshcat's zmq server does (last object and transform
    of each node, its properties in order, its animation) and builds the same standalone page
    from them, so writing HTML needs no server, no port and no subprocess.
    """

    server_proc = None
    zmq_url = None
    web_url = None

    def __init__(self) -> None:
        from meshcat.servers.tree import SceneTree

        self.tree = SceneTree()

    def send(self, command: Any) -> None:
        """Record one meshcat command (``SetObject``, ``SetTransform``, ...)."""
        import umsgpack
        from meshcat.servers.tree import SceneTree, find_node

        data = command.lower()
        kind = data["type"]
        path = [name for name in data["path"].split("/") if name]
        packed = umsgpack.packb(data)
        if kind == "delete":
            if path:
                find_node(self.tree, path[:-1]).pop(path[-1], None)
            else:
                self.tree = SceneTree()
            return
        node = find_node(self.tree, path)
        if kind == "set_transform":
            node.transform = packed
        elif kind == "set_object":
            node.object = packed
            node.properties = []
        elif kind == "set_property":
            node.properties.append(packed)
        elif kind == "set_animation":
            node.animation = packed
        else:
            raise ValueError(f"an offline scene cannot handle meshcat command {kind!r}")

    def get_scene(self) -> str:
        """The standalone HTML page of the recorded scene."""
        import meshcat.servers.zmqserver as server
        from meshcat.servers.tree import walk

        commands = ""
        for node in walk(self.tree):
            for blob in (node.object, *node.properties, node.transform, node.animation):
                if blob is not None:
                    commands += server.create_command(blob)
        script = Path(server.VIEWER_ROOT) / "main.min.js"
        return _STATIC_HTML.format(mainminjs=script.read_text(encoding="utf-8"), commands=commands)


def offline_visualizer() -> meshcat.Visualizer:
    """A visualizer that records the scene in-process, for writing standalone HTML.

    It accepts every scene command of a served visualizer and its
    ``static_html()`` returns the page a meshcat server would return for the
    same commands, but there is no server and no URL: nothing can fail to
    start and nothing needs stopping.  Use it whenever only a file is wanted.

    Returns:
        A ``meshcat.Visualizer`` rooted at ``/meshcat``.
    """
    import meshcat

    return meshcat.Visualizer(window=_SceneRecorder())
