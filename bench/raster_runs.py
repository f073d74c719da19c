#!/usr/bin/env python3
"""Spread of the raster passes over repeated runs, configurations interleaved.

Each round runs every configuration once (A, B, C, A, B, C, ...), each run a
fresh `penumbra render` process that renders --frames frames; the last frame's
stats are kept. Prints, per configuration and stage, the median, the fastest,
the slowest and slowest / fastest (the spread), plus the process's minor page
faults and CPU seconds (from /usr/bin/time), which are steadier than wall
times on a shared machine.

  bench/raster_runs.py MODEL [--rounds 5] [--frames 4] [--size 1024]
        [--config NAME='ENV=VALUE ... -- extra render options'] ...
  e.g. bench/raster_runs.py big.penumbra --config all='-- --cull all' --config none='-- --cull none'

A configuration is environment assignments, then `--`, then render options
(either part may be empty); BIN=path among the assignments runs another
penumbra binary (A/B of two builds). Default configurations: --cull all and
--cull none. With PENUMBRA_FLOOR_CLOCK=cpu and --floors, pass times are the
process's CPU time, steady on a shared machine.
"""
import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile


def parse_config(text):
    name, _, spec = text.partition('=')
    env_part, _, opt_part = spec.partition('--')
    env = dict(item.split('=', 1) for item in shlex.split(env_part))
    return name, env, shlex.split(opt_part)


def run_once(penumbra, model, size, frames, shadows, env, options, tmp):
    env = dict(env)
    penumbra = env.pop('BIN', penumbra)
    stats = os.path.join(tmp, 'stats.json')
    timing = os.path.join(tmp, 'time.txt')
    cmd = ['/usr/bin/time', '-o', timing, '-f', '%R %U %S %M', penumbra, 'render', model, '-o', os.path.join(tmp, 'out.png'),
           '--size', str(size), '--frames', str(frames), '--shadows', shadows, '--stats', stats] + options
    subprocess.run(cmd, env={**os.environ, **env}, check=True, stdout=subprocess.DEVNULL)
    faults, user, system, rss = open(timing).read().split()[-4:]
    d = json.load(open(stats))
    row = {k[:-3]: v for k, v in d['passes'].items()}
    row['gpu'] = d['gpu_ms']
    row['faults'] = float(faults)
    row['cpu_s'] = float(user) + float(system)
    row['rss_mb'] = float(rss) / 1024
    for view in d.get('views', []):
        row['culled_%s_pct' % view['name']] = 100.0 * view['triangles_culled'] / max(1, view['triangles_drawn'] + view['triangles_culled'])
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('model')
    ap.add_argument('--penumbra', default=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'build', 'penumbra'))
    ap.add_argument('--rounds', type=int, default=5)
    ap.add_argument('--frames', type=int, default=4)
    ap.add_argument('--size', type=int, default=1024)
    ap.add_argument('--shadows', default='sm')
    ap.add_argument('--config', action='append', default=[])
    ap.add_argument('--stages', default='camera,shadow_map,camera_floor,shadow_map_floor,gpu,cpu_s,faults')
    args = ap.parse_args()
    configs = [parse_config(c) for c in (args.config or ['all=-- --cull all', 'none=-- --cull none'])]
    runs = {name: [] for name, _, _ in configs}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for name, env, options in configs:
                row = run_once(args.penumbra, args.model, args.size, args.frames, args.shadows, env, options, tmp)
                runs[name].append(row)
                print('round %d %-12s %s' % (r + 1, name, ' '.join('%s=%.0f' % (k, row[k]) for k in args.stages.split(',') if k in row)),
                      file=sys.stderr, flush=True)
    print('| config | stage | median | fastest | slowest | slowest / fastest | runs |')
    print('|---|---|---|---|---|---|---|')
    for name, _, _ in configs:
        keys = [k for k in args.stages.split(',') if all(k in row for row in runs[name])]
        keys += sorted(k for k in runs[name][0] if k.startswith('culled_'))
        for k in keys:
            values = [row[k] for row in runs[name]]
            lo, hi = min(values), max(values)
            print('| %s | %s | %.1f | %.1f | %.1f | %s | %s |' % (name, k, statistics.median(values), lo, hi,
                                                               '%.2f' % (hi / lo) if lo > 0 else '-',
                                                               ' '.join('%.0f' % v for v in values)))


if __name__ == '__main__':
    main()
