"""``lightprobe view``: the three papers live in WebGL2 (top floor, beside ``demo`` and the CLI).

* :mod:`.bake` — everything the page needs, computed by the Python API into one folder (format ``lightprobe.view``).
* :mod:`.server` — a static server for that folder and the page, on 127.0.0.1 only, GET/HEAD only.
* :mod:`.page` — headless Chromium (Playwright) driving the page: read-backs for the tests, screenshots for the demo.
* ``static/`` — the page itself: three.js (from npm, never copied into the repository) for the scene and the loop,
  lightprobe's own shaders where the papers' algorithms live.
"""
