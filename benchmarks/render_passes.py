"""Where the colour pass's time goes on this machine's rasteriser, and what 4x multisampling costs
(what `bench_render.py`'s "colour" row holds: issue 16's 250 ms render target is mostly this pass).

    PYOPENGL_PLATFORM=egl .venv/bin/python benchmarks/render_passes.py [--frames 12] [--samples 4|2|0]

Per world of scenes/urban.yaml (the spec's seed, frames 0..N-1), median ms over the worlds:
- first draw: the colour pass as a frame runs it (the scene's meshes uploaded, drawn, resolved,
  read back: pyrender's read-back of colour and depth);
- drawn again: the same pass once the meshes are in the GL context (no upload);
- nothing drawn: the same pass with every mesh hidden (clear, resolve, read-back alone);
- read-back: pyrender's resolve and read of the colour and depth just drawn, and of the colour
  alone (the colour pass's depth is never used).
`--samples 0` builds it without multisampling (pyrender hard-codes 4; GL reads 0 as none): a what-if,
the images differ, so the generator keeps 4.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pyrender.renderer
from OpenGL.GL import (GL_COLOR_BUFFER_BIT, GL_DRAW_FRAMEBUFFER, GL_LINEAR, GL_READ_FRAMEBUFFER, GL_RGBA,
                       GL_UNSIGNED_BYTE, glBindFramebuffer, glBlitFramebuffer, glFinish, glReadPixels)
from pyrender.constants import RenderFlags

from simgen.render import build_scene, renderer
from simgen.sample import sample_world
from simgen.spec import load_spec


def _with_samples(n: int) -> None:
    """Make pyrender's multisampled framebuffer with n samples (before its first render)."""
    storage = pyrender.renderer.glRenderbufferStorageMultisample
    pyrender.renderer.glRenderbufferStorageMultisample = (
        lambda target, _samples, fmt, w, h: storage(target, n, fmt, w, h))


def _ms(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return 1000 * (time.perf_counter() - t0)


def _colour_only(r) -> None:
    """Resolve and read the colour of the pass just drawn, without its depth."""
    gl = r._renderer
    w, h = gl._main_fb_dims
    glBindFramebuffer(GL_READ_FRAMEBUFFER, gl._main_fb_ms)
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, gl._main_fb)
    glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_LINEAR)
    glBindFramebuffer(GL_READ_FRAMEBUFFER, gl._main_fb)
    glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--samples", type=int, default=4, help="samples of the colour framebuffer")
    args = ap.parse_args()
    if args.samples != 4:
        _with_samples(args.samples)
    spec = load_spec("scenes/urban.yaml")
    worlds = [sample_world(spec, spec.seed, i) for i in range(args.frames)]
    r = renderer(worlds[0].rig.width, worlds[0].rig.height)
    build_scene(worlds[0]).colour_pass(r)  # warm-up: shaders compile on the first render
    t: dict[str, list[float]] = {k: [] for k in ("first draw", "drawn again", "nothing drawn",
                                                 "read-back, colour and depth", "read-back, colour alone")}
    for w in worlds:
        built = build_scene(w)
        t["first draw"].append(_ms(lambda: built.colour_pass(r)))
        t["drawn again"].append(_ms(lambda: built.colour_pass(r)))
        r._platform.make_current()
        glFinish()
        t["read-back, colour and depth"].append(_ms(lambda: r._renderer._read_main_framebuffer(
            built.scene, built.flags | RenderFlags.OFFSCREEN)))
        t["read-back, colour alone"].append(_ms(lambda: _colour_only(r)))
        r._platform.make_uncurrent()
        shown = [(m, m.is_visible) for m in built.scene.meshes]
        for m, _ in shown:
            m.is_visible = False
        t["nothing drawn"].append(_ms(lambda: r.render(built.scene, flags=built.flags)))
        for m, visible in shown:
            m.is_visible = visible
    print(f"urban: {args.frames} frames of {worlds[0].rig.width}x{worlds[0].rig.height}, "
          f"colour framebuffer with {args.samples} sample(s)")
    for k, v in t.items():
        print(f"  {k:28s} {np.median(v):7.1f} ms median")


if __name__ == "__main__":
    main()
