"""Both reports in a real browser (Debian's headless Chromium; `.ci/run` installs it).

Method:

* **Not blank**: Chromium's own screenshot (``--screenshot``) of each page must show text and the
  embedded figures: pixel spread, many distinct colours, and colourful (non-grey) pixels, which
  only the decoded PNG figures produce.
* **No external resource**: Chromium runs with every network request sent to a recording
  proxy on 127.0.0.1 (``--proxy-server`` with ``--proxy-bypass-list=<-loopback>``, so nothing
  goes direct), the page's Content-Security-Policy removed so the check is of the page's
  content, not of its policy, and Chromium's own background services switched off or pointed
  at a dead address. A control page with one external image and one external stylesheet must
  reach its proxy (so the method can see a fetch), and the reports must not. Requests the control run shows besides its two injected ones are Chromium's own
  and are ignored. The policy itself is checked by the parser-level scan in test_report.py.
"""

from __future__ import annotations

import os
import re
import shutil
import socketserver
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from report_inputs import pair_inputs, sequence_report

from irfidelity.report import render_pair_html, render_sequence_html

CANARY_HOSTS = ("canary.invalid", "cdn.canary.invalid")
CANARY = ('<img src="http://canary.invalid/pixel.png" alt="">'
          '<link rel="stylesheet" href="https://cdn.canary.invalid/style.css">')
QUIET = [
    "--disable-background-networking", "--disable-component-update", "--disable-sync", "--disable-extensions",
    "--disable-default-apps", "--disable-domain-reliability", "--no-pings", "--no-first-run",
    "--no-default-browser-check", "--disable-client-side-phishing-detection", "--dns-prefetch-disable",
    "--safebrowsing-disable-auto-update", "--metrics-recording-only", "--password-store=basic",
    "--disable-features=NetworkTimeServiceQuerying,OptimizationHints,MediaRouter,Translate,"
    "AutofillServerCommunication,CertificateTransparencyComponentUpdater,DialMediaRouteProvider",
    # Google and sign-in service addresses: a closed local port (never the page's business)
    "--google-base-url=http://127.0.0.1:9", "--gaia-url=http://127.0.0.1:9", "--lso-url=http://127.0.0.1:9",
]


def chromium() -> str:
    for name in (os.environ.get("IRFIDELITY_CHROMIUM"), "chromium", "chromium-browser", "google-chrome"):
        if name and shutil.which(name):
            return shutil.which(name)
    why = ("headless Chromium is needed for the browser test: apt-get install chromium (.ci/run installs it when "
           "missing), or set IRFIDELITY_CHROMIUM")
    if os.environ.get("IRFIDELITY_REQUIRE_TOOLS"):
        pytest.fail(why)  # CI: the browser is installed, so this test always runs there
    pytest.skip(why)  # a newcomer's machine: every other test still runs


class Recorder(socketserver.ThreadingTCPServer):
    """A proxy that answers nothing but records the first line of every request."""

    daemon_threads = True

    def __init__(self):
        self.requests: list[str] = []
        outer = self

        class Handler(socketserver.StreamRequestHandler):
            def handle(self):
                outer.requests.append(self.rfile.readline(8192).decode("latin-1").strip())
                try:
                    self.wfile.write(b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\nConnection: close\r\n\r\n")
                except OSError:
                    pass

        super().__init__(("127.0.0.1", 0), Handler)


def load_pages(pages: dict[str, tuple[str, int]], root: Path) -> dict[str, tuple[np.ndarray, list[str]]]:
    """Screenshot every page in its own Chromium (run side by side, each behind its own recording
    proxy), and the hosts each page made its browser contact."""
    exe = chromium()
    runs = {}
    for name, (page, height) in pages.items():
        html, shot = root / f"{name}.html", root / f"{name}.png"
        html.write_text(page, encoding="utf-8")
        proxy = Recorder()
        threading.Thread(target=proxy.serve_forever, daemon=True).start()
        cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--window-size=1100,{height}",
               f"--screenshot={shot}", f"--user-data-dir={root / ('profile-' + name)}",
               f"--proxy-server=http://127.0.0.1:{proxy.server_address[1]}", "--proxy-bypass-list=<-loopback>",
               *QUIET, html.as_uri()]
        runs[name] = (subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL), proxy, shot)
    out = {}
    for name, (proc, proxy, shot) in runs.items():
        try:
            assert proc.wait(timeout=90) == 0, f"chromium failed on the {name} page"
        finally:
            proxy.shutdown()
            proxy.server_close()
        out[name] = (np.asarray(Image.open(shot).convert("RGB")), [_host(r) for r in proxy.requests if r])
    return out


def _host(request_line: str) -> str:
    """The host of a proxy request line (``GET http://h/p HTTP/1.1`` or ``CONNECT h:443 ...``)."""
    target = request_line.split()[1] if len(request_line.split()) > 1 else request_line
    target = re.sub(r"^[a-z]+://", "", target)
    return target.split("/")[0].split(":")[0]


def _without_policy(page: str) -> str:
    return re.sub(r'<meta http-equiv="Content-Security-Policy"[^>]*>', "", page)


def _not_blank(pixels: np.ndarray) -> None:
    assert pixels.shape[0] > 500 and pixels.std() > 20, "blank screenshot"
    colours = np.unique(pixels.reshape(-1, 3)[::7], axis=0)
    assert len(colours) > 300, f"only {len(colours)} colours"
    spread = pixels.max(axis=2).astype(int) - pixels.min(axis=2)
    assert (spread > 60).mean() > 0.002, "no coloured figures drawn"


def test_reports_render_and_fetch_nothing(tmp_path):
    p = pair_inputs()
    pair_page = render_pair_html(p["report"], real=p["real"], sim=p["sim"], curves=p["curves"])
    seq_page = render_sequence_html(sequence_report(300, failed_every=41))
    # the control: a page with an external image and stylesheet; the method must see both
    control = f"<!DOCTYPE html><html><body><h1>control</h1>{CANARY}</body></html>"
    seen = load_pages({"control": (control, 400), "pair": (_without_policy(pair_page), 3200),
                       "sequence": (_without_policy(seq_page), 2600)}, tmp_path)
    control_hosts = seen["control"][1]
    assert set(CANARY_HOSTS) <= set(control_hosts), control_hosts
    background = set(control_hosts) - set(CANARY_HOSTS)  # Chromium's own requests, if any
    for name in ("pair", "sequence"):
        pixels, hosts = seen[name]
        assert set(hosts) <= background, f"{name} report fetched {set(hosts) - background}"
        _not_blank(pixels)
