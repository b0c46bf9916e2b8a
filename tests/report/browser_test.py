#!/usr/bin/env python3
"""`emcalign report` in a real browser: every section from small inputs made here, the page
rendered by headless Chromium (Debian's `chromium`).

Checks:
  - the page is self-contained: no script, style sheet, font or image by URL; every image a
    data: URI;
  - in Chromium: every figure has loaded and has a non-zero size, every table is laid out,
    and the page made no request (the Resource Timing entries are empty);
  - a screenshot is not blank (many colours, a fair share of ink).

  browser_test.py EMCALIGN [--keep DIR]
"""

import argparse
import html.parser
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

PERIOD = """{"format": "emcalign-period/1", "first_run": 1, "runs": 16, "events_per_run": [2500, 3000],
  "seed": 5, "theta_range_deg": [40, 140],
  "beam_energy_mev": [{"from_run": 1, "value": 612.5}],
  "segments": [{"from_run": 1, "parameters": {"alpha": 2.8, "dx": 0.3, "dp1": 0.5}},
               {"from_run": 9, "parameters": {"dx": 0.8}}]}"""

# Appended to a copy of the page: measures every figure and table once the page has loaded,
# and lists the resources fetched, into an attribute that --dump-dom prints.
PROBE = """<script>
window.addEventListener('load', () => {
  const figures = [...document.querySelectorAll('img')].map(e => ({
    complete: e.complete, natural: e.naturalWidth, width: e.getBoundingClientRect().width,
    height: e.getBoundingClientRect().height, alt: e.alt}));
  const tables = [...document.querySelectorAll('table')].map(e => e.getBoundingClientRect().height);
  const resources = performance.getEntriesByType('resource').map(r => r.name);
  document.body.setAttribute('data-probe', JSON.stringify({figures, tables, resources,
    sections: [...document.querySelectorAll('section')].map(s => s.id)}));
});
</script>"""


def run(argv, cwd):
    r = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        raise SystemExit(f"FAIL: {' '.join(argv)} exited {r.returncode}\n{r.stdout}\n{r.stderr}")
    return r


def chromium(*args):
    binary = shutil.which("chromium")
    if binary is None:
        raise SystemExit("FAIL: chromium not found (scripts/install-deps installs Debian's chromium)")
    # --no-sandbox: CI runs as root. No network: the page must not need it.
    return subprocess.run([binary, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           "--host-resolver-rules=MAP * ~NOTFOUND", *args],
                          capture_output=True, text=True, timeout=120)


class Links(html.parser.HTMLParser):
    """Every URL the page names, and the tags that would run or fetch something."""

    def __init__(self):
        super().__init__()
        self.urls, self.forbidden, self.images = [], [], 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag in ("script", "link", "iframe", "object", "embed"):
            self.forbidden.append(tag)
        if tag == "img":
            self.images += 1
        for key in ("src", "href", "srcset", "data", "poster"):
            if key in a and a[key] is not None:
                self.urls.append((tag, key, a[key]))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("emcalign")
    parser.add_argument("--keep", help="make the inputs and the page in this directory and keep them")
    args = parser.parse_args()
    E = os.path.abspath(args.emcalign)
    d = args.keep or tempfile.mkdtemp(prefix="emcalign-report-test-")
    os.makedirs(d, exist_ok=True)
    failures = []
    try:
        params = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "data", "examples",
                              "paper-like.json")
        run([E, "simulate", "--events", "30000", "--params", params, "--theta-min", "40", "--theta-max", "140",
             "--seed", "3", "--no-hits", "-o", "ee.h5"], d)
        grid = os.path.join(os.path.dirname(params), "..", "corrections", "ee-40-140deg")
        run([E, "fit", "ee.h5", "--corrections", grid, "-o", "fit.json"], d)
        run([E, "validate", "--samples", "4", "--events", "4000", "--ideal", "-o", "val"], d)
        run([E, "simulate", "--process", "gg", "--events", "6000", "--params", params, "--seed", "4", "-o", "gg.h5"], d)
        run([E, "check", "gg", "gg.h5", "--alignment", "fit.json", "-o", "chk-gg"], d)
        with open(os.path.join(d, "period.json"), "w") as f:
            f.write(PERIOD)
        run([E, "simulate", "--period", "period.json", "--no-hits", "-o", "period"], d)
        run([E, "campaign", "period", "--conditions", "sqlite:c.db", "--tag", "t", "--min-events", "4000"], d)
        run([E, "trend", "--conditions", "sqlite:c.db", "--tag", "t", "-o", "tr"], d)
        run([E, "report", "--fit", "fit.json", "--events", "ee.h5", "--corrections", grid, "--validation", "val",
             "--trend", "tr",
             "--conditions", "sqlite:c.db", "--tag", "t", "--checks", "chk-gg", "-o", "report.html"], d)
        page = open(os.path.join(d, "report.html"), encoding="utf-8").read()
        run([E, "report", "--fit", "fit.json", "-o", "fit-only.html"], d)
        refused = subprocess.run([E, "report", "--fit", "fit.json", "--events", "gg.h5", "-o", "x.html"], cwd=d,
                                 capture_output=True, text=True)
        if refused.returncode != 1 or "are not the events" not in refused.stderr:
            failures.append(f"the figures of other events were not refused: {refused.returncode} {refused.stderr}")

        # Self-contained.
        links = Links()
        links.feed(page)
        if links.forbidden:
            failures.append(f"the page has {sorted(set(links.forbidden))} elements")
        for tag, key, url in links.urls:
            if not (url.startswith("data:image/png;base64,") or url.startswith("#")):
                failures.append(f"<{tag} {key}> refers outside the page: {url[:80]}")
        if re.search(r"url\(|@import", page):
            failures.append("the styles refer to something by URL")
        if links.images != 9:
            failures.append(f"{links.images} figures; expected the fit's 4, the validation's 2, the trend's 2 and the "
                            "check's")
        if "interpolated to 612.5 MeV" not in page:
            failures.append("the provenance does not show the grid's interpolation")

        # Rendered.
        probe_path = os.path.join(d, "probe.html")
        with open(probe_path, "w", encoding="utf-8") as f:
            f.write(page.replace("</body>", PROBE + "\n</body>"))
        r = chromium("--virtual-time-budget=10000", "--window-size=1280,900", "--dump-dom", "file://" + probe_path)
        m = re.search(r'data-probe="([^"]*)"', r.stdout)
        if r.returncode != 0 or not m:
            failures.append(f"Chromium did not render the page (exit {r.returncode}): {r.stderr[-500:]}")
        else:
            probe = json.loads(html.unescape(m.group(1)))
            for k, fig in enumerate(probe["figures"]):
                if not fig["complete"] or fig["natural"] <= 0 or fig["width"] <= 0 or fig["height"] <= 0:
                    failures.append(f"figure {k} ({fig['alt'][:60]}) did not load or has no size: {fig}")
            if any(h <= 0 for h in probe["tables"]):
                failures.append(f"a table has no height: {probe['tables']}")
            if probe["resources"]:
                failures.append(f"the page requested {probe['resources']}")
            if probe["sections"] != ["summary", "calibration", "validation", "time-evolution", "checks"]:
                failures.append(f"sections {probe['sections']}")
            print(f"rendered: {len(probe['figures'])} figures, {len(probe['tables'])} tables, sections "
                  f"{probe['sections']}, {len(probe['resources'])} requests")

        # The page with --fit alone renders too.
        r = chromium("--virtual-time-budget=5000", "--dump-dom", "file://" + os.path.join(d, "fit-only.html"))
        if r.returncode != 0 or 'id="calibration"' not in r.stdout or "<nav>" in r.stdout:
            failures.append(f"the page of --fit alone did not render as one section (exit {r.returncode})")

        # Not blank, down to its end: a screenshot of the whole page, cut into bands of 800 px.
        shot = os.path.join(d, "report.png")
        r = chromium("--window-size=1280,24000", f"--screenshot={shot}", "file://" + os.path.join(d, "report.html"))
        if not os.path.exists(shot):
            failures.append(f"no screenshot: {r.stderr[-500:]}")
        else:
            from PIL import Image
            im = Image.open(shot).convert("RGB")
            small = im.resize((im.width // 4, im.height // 4))
            w, h = small.size
            rows = [list(small.crop((0, y, w, y + 1)).getdata()) for y in range(h)]
            inked = [any(sum(p) < 600 for p in row) for row in rows]
            end = max((y for y in range(h) if inked[y]), default=0)
            bands = [inked[y:y + 200] for y in range(0, end, 200)]
            blank = sum(1 for b in bands if not any(b))
            colours = len(set(small.crop((0, 0, w, end + 1)).getdata()))
            print(f"screenshot {im.width}x{4 * end}: {colours} colours, {len(bands)} bands of 800 px, {blank} blank")
            if colours < 50 or len(bands) < 10 or blank > 0:
                failures.append(f"the page looks blank in places: {colours} colours, {len(bands)} bands, {blank} blank")
    finally:
        if not args.keep:
            shutil.rmtree(d, ignore_errors=True)
    for f in failures:
        print("FAIL:", f)
    if failures:
        sys.exit(1)
    print("ok: the report is self-contained and renders in Chromium")


if __name__ == "__main__":
    main()
