"""A small DevTools-protocol driver for Debian's headless chromium, shared by the web tests.
Importing it exits 77 (skipped) when chromium or python3-websocket is missing."""
import json
import os
import shutil
import sys
import time

try:
    import websocket  # python3-websocket
except ImportError:
    print("WEB SKIP: python3-websocket is missing (deploy/setup.sh installs it)")
    sys.exit(77)

CHROMIUM = shutil.which("chromium")
if not CHROMIUM:
    print("WEB SKIP: Debian's chromium is not installed (deploy/setup.sh installs it)")
    sys.exit(77)


class Failure(Exception):
    pass


class Cdp:
    """A DevTools protocol client over the browser's WebSocket (flat sessions)."""

    def __init__(self, url):
        self.ws = websocket.create_connection(url, timeout=60, suppress_origin=True)
        self.next_id = 0

    def call(self, method, params=None, session=None):
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        self.ws.send(json.dumps(message))
        while True:
            reply = json.loads(self.ws.recv())
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise Failure(f"{method}: {reply['error']}")
                return reply["result"]

    def open_tab(self, url):
        target = self.call("Target.createTarget", {"url": url})["targetId"]
        return self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]

    def evaluate(self, session, expression):
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session)
        if "exceptionDetails" in result:
            raise Failure(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")


def start_chromium(start, profile):
    """Starts headless chromium through start(name, args) and returns (process, Cdp)."""
    chromium = start("chromium", [
        CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader", "--remote-debugging-port=0", f"--user-data-dir={profile}",
        "--no-first-run", "--disable-extensions", "--disable-background-networking",
        "--disable-background-timer-throttling", "--disable-renderer-backgrounding",
        "--disable-backgrounding-occluded-windows", "--window-size=1100,700", "about:blank"])
    end = time.time() + 30
    while not os.path.exists(f"{profile}/DevToolsActivePort"):
        if chromium.poll() is not None or time.time() > end:
            raise Failure("chromium did not start its DevTools endpoint")
        time.sleep(0.1)
    time.sleep(0.2)
    with open(f"{profile}/DevToolsActivePort") as f:
        devtools_port, path = f.read().split()[:2]
    return chromium, Cdp(f"ws://127.0.0.1:{devtools_port}{path}")


def wait_stats(cdp, tab, condition, seconds, what):
    end = time.time() + seconds
    stats = None
    while time.time() < end:
        stats = cdp.evaluate(tab, "JSON.stringify({...window.vdeformStats, dom: {...document.getElementById('vd-stats')?.dataset}})")
        stats = json.loads(stats) if stats else None
        if stats and condition(stats):
            return stats
        time.sleep(0.2)
    raise Failure(f"{what} within {seconds} s; the page shows {stats}")
