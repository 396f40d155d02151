"""What a replay page shows besides the 3D scene: title, play/pause, time slider, readouts.

Meshcat's page hides its animation controls in a folded menu and has no notion of a run. The
overlay written here names the run (the page title and a heading: robot and experiment), puts a
play/pause button, a time slider and a readout of the time and the largest feature error
``max |xi - xi_d|`` [px] along the bottom edge, and draws the camera's image in a corner: the
current image points (red dots) and the desired ones ``xi_d`` (green rings), at a size that
reads at a glance. Everything is plain HTML and one script that reads ``viewer.animator``; the
data it shows is embedded as JSON, so the page still needs no server.
"""

from __future__ import annotations

import html
import json
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

INSET_WIDTH = 220
"""Width of the camera-image inset [CSS px]; its height follows the image's aspect ratio."""

ELEMENT_IDS = {
    "title": "pbvs-title",
    "play": "pbvs-play",
    "slider": "pbvs-slider",
    "readout": "pbvs-readout",
    "image": "pbvs-image",
}
"""HTML ids of the overlay's elements (the tests find them by these)."""


@dataclass(frozen=True)
class ReplayOverlay:
    """The data the overlay shows, one row per replay key.

    Attributes:
        title: The page's title, naming the robot and the experiment.
        subtitle: One line under the title (the scenario's description), or empty.
        times: Key times from the replay's start [s]. Shape (K,).
        error_px: Largest absolute feature error ``max_i |xi_i - xi_d,i|`` at each key [px],
            NaN where the target was not seen. Shape (K,).
        points_px: Current image points of the two spheres at each key, as pixel
            ``(col, row)`` from the image's top-left corner. Shape (K, 2, 2).
        desired_px: Desired image points as pixel ``(col, row)``. Shape (2, 2).
        image_size: Image ``(width, height)`` [px].
    """

    title: str
    subtitle: str
    times: npt.NDArray[np.float64]
    error_px: npt.NDArray[np.float64]
    points_px: npt.NDArray[np.float64]
    desired_px: npt.NDArray[np.float64]
    image_size: tuple[int, int]

    def data(self) -> dict:
        """The overlay's data as JSON-ready lists (NaN as ``None``)."""

        def listed(values: np.ndarray, digits: int) -> list:
            rounded = np.round(np.asarray(values, dtype=float), digits)
            return np.where(np.isfinite(rounded), rounded, None).tolist()

        return {
            "title": self.title,
            "times": listed(self.times, 4),
            "error": listed(self.error_px, 2),
            "points": listed(self.points_px, 2),
            "desired": listed(self.desired_px, 2),
            "image": [int(self.image_size[0]), int(self.image_size[1])],
            "ids": ELEMENT_IDS,
            "inset_width": INSET_WIDTH,
        }


STYLE = """<style>
#pbvs-head { position: fixed; top: 0; left: 0; padding: 6px 12px; max-width: 60%;
  background: rgba(10, 10, 20, 0.78); color: #fff; font: 15px/1.3 sans-serif; z-index: 10;
  border-bottom-right-radius: 6px; }
#pbvs-title { font-weight: bold; font-size: 17px; }
#pbvs-subtitle { font-size: 12px; color: #ccc; }
#pbvs-inset { position: fixed; left: 8px; top: 64px; padding: 4px; z-index: 10;
  background: rgba(10, 10, 20, 0.78); color: #fff; font: 12px sans-serif; border-radius: 4px; }
#pbvs-image { display: block; }
#pbvs-bar { position: fixed; left: 0; right: 0; bottom: 0; height: 46px; z-index: 10;
  display: flex; align-items: center; gap: 12px; padding: 0 12px;
  background: rgba(10, 10, 20, 0.85); color: #fff; font: 15px sans-serif; }
#pbvs-play { width: 76px; height: 30px; font: bold 14px sans-serif; cursor: pointer;
  background: #2f6fdf; color: #fff; border: 0; border-radius: 4px; }
#pbvs-slider { flex: 1; height: 24px; accent-color: #2f6fdf; }
#pbvs-readout { font: 15px monospace; white-space: pre; min-width: 330px; }
</style>"""

BODY = """<div id="pbvs-head"><div id="pbvs-title">{title}</div>
<div id="pbvs-subtitle">{subtitle}</div></div>
<div id="pbvs-inset">camera image: <span style="color:#ff4040">&#9679; now</span>
<span style="color:#40ff40">&#9675; desired</span>
<canvas id="pbvs-image"></canvas></div>
<div id="pbvs-bar"><button id="pbvs-play" type="button">Pause</button>
<input id="pbvs-slider" type="range" min="0" step="0.01" value="0" aria-label="time">
<span id="pbvs-readout"></span></div>"""

SCRIPT = """<script>
(function () {
  const D = %s;
  document.title = D.title;
  const el = {};
  for (const [key, id] of Object.entries(D.ids)) el[key] = document.getElementById(id);
  const times = D.times, last = times.length - 1;
  el.slider.max = times[last];
  const canvas = el.image, ctx = canvas.getContext("2d");
  const scale = D.inset_width / D.image[0];
  canvas.width = D.inset_width;
  canvas.height = Math.round(D.image[1] * scale);
  let dragging = false;

  function now() {
    const a = viewer.animator;
    return a.actions.reduce((m, x) => Math.max(m, x.time), 0);
  }
  function key(t) {  // the last key at or before t
    let lo = 0, hi = last;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (times[mid] <= t + 1e-6) lo = mid; else hi = mid - 1;
    }
    return lo;
  }
  function dot(p, r, color, fill) {
    if (p[0] === null || p[1] === null) return;
    ctx.beginPath();
    ctx.arc(p[0] * scale, p[1] * scale, r, 0, 2 * Math.PI);
    if (fill) { ctx.fillStyle = color; ctx.fill(); }
    else { ctx.strokeStyle = color; ctx.lineWidth = 2.5; ctx.stroke(); }
  }
  function draw(k) {
    ctx.fillStyle = "#202028"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    ctx.strokeStyle = "#888"; ctx.lineWidth = 1;
    ctx.strokeRect(0.5, 0.5, canvas.width - 1, canvas.height - 1);
    ctx.beginPath();  // the image's centre lines
    ctx.moveTo(canvas.width / 2, 0); ctx.lineTo(canvas.width / 2, canvas.height);
    ctx.moveTo(0, canvas.height / 2); ctx.lineTo(canvas.width, canvas.height / 2);
    ctx.strokeStyle = "#444"; ctx.stroke();
    for (const p of D.desired) dot(p, 8, "#40ff40", false);
    for (const p of D.points[k]) dot(p, 5, "#ff4040", true);
  }
  function update() {
    const t = now(), k = key(t), e = D.error[k];
    const error = e === null ? "target not seen" : e.toFixed(1) + " px";
    el.readout.textContent = "t = " + t.toFixed(1).padStart(5) + " s   max |xi - xi_d| = " + error;
    if (!dragging) el.slider.value = t;
    el.play.textContent = viewer.animator.playing ? "Pause" : "Play";
    draw(k);
  }
  el.play.addEventListener("click", () => {
    const a = viewer.animator;
    if (a.playing) a.pause(); else a.play();
    update();
  });
  el.slider.addEventListener("input", () => {
    dragging = true;
    viewer.animator.seek(parseFloat(el.slider.value));
    update();
  });
  el.slider.addEventListener("change", () => { dragging = false; update(); });
  const render = viewer.render.bind(viewer);
  viewer.render = function () { render(); update(); };
  update();
})();
</script>
</body>"""


def overlay_html(overlay: ReplayOverlay) -> str:
    """The overlay's style, elements and script, ending with ``</body>``."""
    body = BODY.format(title=html.escape(overlay.title), subtitle=html.escape(overlay.subtitle))
    return STYLE + "\n" + body + "\n" + SCRIPT % json.dumps(overlay.data())


def add_overlay(page: str, overlay: ReplayOverlay) -> str:
    """A replay page with the overlay added before its closing ``</body>``.

    Args:
        page: A standalone meshcat page.
        overlay: What to show.

    Returns:
        The page with its ``<title>`` set and the overlay added.
    """
    head, _, tail = page.rpartition("</body>")
    head = head.replace("<title>MeshCat</title>", f"<title>{html.escape(overlay.title)}</title>")
    return head + overlay_html(overlay) + tail
