#!/usr/bin/env python3
"""Process CPU ms per frame of shadow methods, scenes and methods interleaved.

Each run is a fresh `penumbra render SCENE.penumbra --frames 3 --floors` with
PENUMBRA_FLOOR_CLOCK=cpu, so every pass interval is the process's CPU time
(lavapipe's threads included), steady on a shared machine; a frame's cost is
the sum of its passes without the `_floor` ones (host culling not included).
Prints every run, then the median per scene and method and afsm's ratios.

  bench/method_cpu.py DIR SIZE ROUNDS city,interior,plant,scan sm,srt,frt,afsm [render options...]
  (DIR holds SCENE.penumbra: penumbra generate SCENE --triangles 250000 -o SCENE.glb;
   penumbra preprocess SCENE.glb -o SCENE.penumbra. BIN=path runs another build.)
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile

binary = os.environ.get("BIN", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build", "penumbra"))
folder, size, rounds, scenes, methods = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4].split(","), sys.argv[5].split(",")
extra = sys.argv[6:]
env = dict(os.environ, PENUMBRA_FLOOR_CLOCK="cpu")
results = {}
with tempfile.TemporaryDirectory() as tmp:
    for r in range(rounds):
        for scene in scenes:
            for method in methods:
                stats = os.path.join(tmp, "stats.json")
                command = [binary, "render", os.path.join(folder, scene + ".penumbra"), "--size", size, "--shadows", method,
                           "--frames", "3", "--floors", "--stats", stats, "-o", os.path.join(tmp, "image.png")] + extra
                run = subprocess.run(command, env=env, capture_output=True, text=True)
                if run.returncode:
                    print(scene, method, "FAILED:", run.stderr.strip()[-300:], flush=True)
                    continue
                with open(stats) as f:
                    passes = {k: v for k, v in json.load(f)["passes"].items() if not k.endswith("_floor_ms")}
                total = sum(passes.values())
                results.setdefault((scene, method), []).append(total)
                print(f"round {r} {scene:9s} {method:5s} {total:8.1f} ms  " + " ".join(f"{k[:-3]} {v:.1f}" for k, v in passes.items()),
                      flush=True)
print(f"\nmedian CPU ms per frame (sum of passes), {size}^2")
for scene in scenes:
    row = {m: statistics.median(results[(scene, m)]) for m in methods if (scene, m) in results}
    line = f"{scene:9s} " + " ".join(f"{m} {v:7.1f}" for m, v in row.items())
    if "afsm" in row:
        line += "  |" + "".join(f" afsm/{m} {row['afsm'] / row[m]:.2f}" for m in ("frt", "sm", "srt") if m in row)
    print(line)
