#!/usr/bin/python3
"""The web page switches between named streams (issue 16), in headless chromium: it opens on the
first stream it is offered, lists both, and after choosing the other one in its stream menu shows
that stream's mesh (the vertex count the native viewer of that stream saved).

    web_streams_check.py PORT WORKDIR STREAM=VERTICES STREAM=VERTICES
Exit 0 pass, 1 fail, 77 skipped (no chromium or python3-websocket).
"""
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp import Failure, start_chromium, wait_stats  # noqa: E402


def main(port, work, expected):
    procs = []

    def start(name, args):
        proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(proc)
        return proc

    try:
        _, cdp = start_chromium(start, os.path.join(work, "chromium-streams"))
        tab = cdp.open_tab(f"http://127.0.0.1:{port}/")
        first = wait_stats(cdp, tab, lambda s: s.get("meshes", 0) >= 1 and s.get("stream") in expected, 20,
                           "the page showed no mesh of either stream")
        if first["vertices"] != expected[first["stream"]]:
            raise Failure(f"stream {first['stream']}: the page shows {first['vertices']} vertices, "
                          f"expected {expected[first['stream']]}")
        listed = cdp.evaluate(tab, "[...document.getElementById('stream').options].map(o => o.value).join(',')")
        if sorted(listed.split(",")) != sorted(expected):
            raise Failure(f"the stream menu lists {listed}, expected {','.join(sorted(expected))}")
        other = next(name for name in expected if name != first["stream"])
        cdp.evaluate(tab, f"(() => {{ const s = document.getElementById('stream'); s.value = '{other}';"
                          " s.dispatchEvent(new Event('change')); })()")
        switched = wait_stats(cdp, tab, lambda s: s.get("stream") == other and s.get("vertices") == expected[other], 10,
                              f"the page did not switch to stream {other}")
        print(f"page: stream {first['stream']} ({first['vertices']} vertices), menu {listed}, switched to "
              f"{other} ({switched['vertices']} vertices)")
        return 0
    except Failure as e:
        print(f"WEB STREAMS FAIL: {e}")
        return 1
    finally:
        for proc in procs:
            proc.terminate()
            proc.wait(10)


if __name__ == "__main__":
    expected = dict((pair.split("=")[0], int(pair.split("=")[1])) for pair in sys.argv[3:])
    sys.exit(main(int(sys.argv[1]), sys.argv[2], expected))
