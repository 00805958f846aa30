"""The HTML report in a real browser: headless Chromium (Debian `chromium`, installed by
scripts/setup.sh) loads the report of a discovery on a user's model file, and a script run in
the page measures every SVG plot: each must draw marks (paths, polylines, circles, rects) of
non-zero size inside its own area. The report itself carries no script; the check is appended
to a copy."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import pytest

import independent_cartpole as ic
from test_interop import stabilis_bin

MODEL = Path(__file__).parent / "data" / "cart_pole.toml"

CHECK = """
<script>
window.addEventListener('load', () => {
  const plots = [...document.querySelectorAll('svg')].map((svg, i) => {
    const box = svg.getBoundingClientRect();
    const marks = [...svg.querySelectorAll('path, polyline, circle, rect, line')]
      .map(el => el.getBBox())
      .filter(b => b.width > 0 || b.height > 0);
    const title = (svg.querySelector('text') || {}).textContent || '';
    return {i, title, width: box.width, height: box.height, marks: marks.length};
  });
  const out = document.createElement('pre');
  out.id = 'plot-check';
  out.textContent = JSON.stringify(plots);
  document.body.appendChild(out);
});
</script>
"""


def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.fail("headless Chromium is not installed (scripts/setup.sh installs Debian's chromium)")


def measured_plots(html: str, tmp_path: Path) -> list[dict]:
    """Every SVG of the page `html` as the browser lays it out: title, size, marks drawn."""
    page = tmp_path / "checked.html"
    page.write_text(html.replace("</body>", CHECK + "</body>"))
    dom = subprocess.run([chromium(), "--headless", "--no-sandbox", "--disable-gpu",
                          "--virtual-time-budget=5000", "--dump-dom", page.as_uri()],
                         capture_output=True, text=True, check=False, timeout=120)
    assert dom.returncode == 0, dom.stderr[-2000:]
    found = re.search(r'<pre id="plot-check">(.*?)</pre>', dom.stdout, re.S)
    assert found, dom.stdout[-2000:]
    return json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))


def test_every_plot_of_the_report_draws(tmp_path):
    data = tmp_path / "runs"
    ic.campaign(data, plant=replace(ic.Plant(), tau=0.03), seed=1)
    report = tmp_path / "report"
    done = subprocess.run([stabilis_bin(), "discover", "--model", str(MODEL), "--data", str(data),
                           "--report", str(report)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    html = (report / "index.html").read_text()
    assert "<script" not in html
    for heading in ("Parameters", "Time domain", "Residual autocorrelation", "Error per step",
                    "Frequency response"):
        assert f"<h2>{heading}" in html, heading
    plots = measured_plots(html, tmp_path)
    # Error per step, the misfit per line, two outputs of measured/predicted, two
    # autocorrelations, and a magnitude and phase panel per FRF entry shown.
    assert len(plots) >= 8, plots
    for p in plots:
        assert p["width"] > 100 and p["height"] > 100, p
        # The frame and at least one drawn series: more than the frame rectangle alone.
        assert p["marks"] >= 2, p
    titles = [p["title"] for p in plots]
    assert any("autocorrelation" in t for t in titles), titles
    assert any("measured and predicted" in t for t in titles), titles
