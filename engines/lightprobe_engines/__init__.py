"""The engines lightprobe's output is checked in, driven from Python: a development harness, never shipped in the
lightprobe wheel.

* :mod:`.runtimes` — three.js, Babylon.js and Filament from the npm packages pinned in ``engines/package.json``:
  pages served to Debian's Chromium (Playwright), Babylon in Node, the comparisons of what comes back;
* :mod:`.viewer_page` — the viewer's page in headless Chromium: read-backs for the tests, screenshots for the demo;
* :mod:`.peak` — a command's peak resident memory, measured from outside it;
* :mod:`.probes` — synthetic probes for the direction checks (a marker off each axis: no view symmetric).

``bash setup.sh`` installs it (editable) into ``.venv`` beside lightprobe; the demo uses it when it is there and says
what it skips when it is not.
"""
