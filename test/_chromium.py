"""Load a page in headless Chromium over the DevTools protocol (websockets): console errors,
each <video>'s readyState once it has decoded frames, and a screenshot."""
from __future__ import annotations

import asyncio
import base64
import json
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import websockets

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
VIDEO_STATE = """JSON.stringify(Array.from(document.querySelectorAll('video')).map(v => ({src: v.currentSrc,
  readyState: v.readyState, width: v.videoWidth, height: v.videoHeight,
  frames: v.getVideoPlaybackQuality ? v.getVideoPlaybackQuality().totalVideoFrames : -1,
  error: v.error ? v.error.code : 0})))"""


@dataclass
class PageReport:
    console_errors: list
    videos: list
    screenshot: Path
    values: list  # what each of `evaluate`'s expressions returned, in order


class _Cdp:
    def __init__(self, ws):
        self.ws, self.n, self.events = ws, 0, []

    async def call(self, method: str, **params):
        self.n += 1
        mid = self.n
        await self.ws.send(json.dumps({"id": mid, "method": method, "params": params}))
        while True:
            msg = json.loads(await self.ws.recv())
            if msg.get("id") == mid:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self.events.append(msg)

    async def evaluate(self, expr: str):
        return (await self.call("Runtime.evaluate", expression=expr, returnByValue=True))["result"].get("value")


def _errors(events: list) -> list:
    out = []
    for e in events:
        m, p = e.get("method"), e.get("params", {})
        if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            out.append(" ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", [])))
        elif m == "Runtime.exceptionThrown":
            out.append(p.get("exceptionDetails", {}).get("text", "exception"))
        elif m == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
            out.append(p["entry"].get("text", ""))
    return out


async def _inspect(port: int, url: str, shot: Path, polls: int, evaluate: tuple[str, ...]) -> PageReport:
    import urllib.request

    targets = json.loads(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10).read())
    page = next(t for t in targets if t.get("type") == "page")
    async with websockets.connect(page["webSocketDebuggerUrl"], max_size=1 << 26) as ws:
        cdp = _Cdp(ws)
        for domain in ("Page", "Runtime", "Log"):
            await cdp.call(f"{domain}.enable")
        await cdp.call("Page.navigate", url=url)
        videos = []
        for _ in range(polls):  # until every video has decoded frames (observable state), bounded
            await cdp.call("Runtime.evaluate", expression="new Promise(r => setTimeout(r, 200))", awaitPromise=True)
            if await cdp.evaluate("document.readyState") != "complete":
                continue
            videos = json.loads(await cdp.evaluate(VIDEO_STATE))
            if all(v["readyState"] >= 2 or v["error"] for v in videos):
                break
        data = (await cdp.call("Page.captureScreenshot", format="png", captureBeyondViewport=True))["data"]
        shot.write_bytes(base64.b64decode(data))
        values = [await cdp.evaluate(e) for e in evaluate]
        return PageReport(_errors(cdp.events), videos, shot, values)


def inspect_page(path: Path, screenshot: Path, polls: int = 300, evaluate: tuple[str, ...] = ()) -> PageReport:
    """Open file `path` in headless Chromium; report console errors, <video> states, a screenshot."""
    profile = tempfile.mkdtemp(prefix="chromium_")
    proc = subprocess.Popen([CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu", "--mute-audio",
                             "--remote-debugging-port=0", f"--user-data-dir={profile}", "--window-size=1200,2000",
                             "--autoplay-policy=no-user-gesture-required", "about:blank"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        port = None
        for line in proc.stderr:  # "DevTools listening on ws://127.0.0.1:<port>/..."
            m = re.search(r"DevTools listening on ws://[^:]+:(\d+)/", line)
            if m:
                port = int(m.group(1))
                break
        if port is None:
            raise RuntimeError(f"chromium exited ({proc.poll()}) without a DevTools port")
        return asyncio.run(_inspect(port, Path(path).resolve().as_uri(), Path(screenshot), polls, tuple(evaluate)))
    finally:
        proc.terminate()
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
        shutil.rmtree(profile, ignore_errors=True)
