#!/usr/bin/env bash
# A/B stage times of two penumbra binaries on one model, interleaved so that
# both see the same machine: ROUNDS rounds of each case with A then B, the
# last of 4 frames at 512^2 per run; prints per-stage medians and B/A.
#   bench/ab_stages.sh OLD_PENUMBRA NEW_PENUMBRA MODEL.penumbra [ROUNDS]
set -euo pipefail
A=$1; B=$2; MODEL=$3; ROUNDS=${4:-3}
out=$(mktemp)
cases=("--shadows sm" "--shadows srt" "--shadows frt" "--shadows srt --light 'sphere position=0,300,200 radius=8 intensity=200000' --samples 16")
for _ in $(seq "$ROUNDS"); do
  for c in "${cases[@]}"; do
    for bin in A B; do
      eval "${!bin}" render "$MODEL" -o /tmp/ab_stages.png --size 512 --frames 4 "$c" --stats /tmp/ab_stages.json > /dev/null
      CASE="$c" BIN=$bin python3 -c "
import json, os
d = json.load(open('/tmp/ab_stages.json'))
stages = ' '.join('%s=%.3f' % (k[:-3], v) for k, v in d['passes'].items())
print('%s|%s|%.3f|%s' % (os.environ['BIN'], os.environ['CASE'].split(\"'\")[0].strip(), d['gpu_ms'], stages))" >> "$out"
    done
  done
done
python3 - "$out" <<'PY'
import collections, statistics, sys
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    binary, case, gpu, stages = line.strip().split('|')
    runs[(case, binary, 'gpu')].append(float(gpu))
    for kv in stages.split():
        name, value = kv.split('=')
        runs[(case, binary, name)].append(float(value))
print('| case | stage | A median ms | B median ms | B / A |\n|---|---|---|---|---|')
for case, binary, stage in sorted(k for k in runs if k[1] == 'A'):
    if (case, 'B', stage) in runs:
        a, b = statistics.median(runs[(case, 'A', stage)]), statistics.median(runs[(case, 'B', stage)])
        print('| %s | %s | %.1f | %.1f | %s |' % (case, stage, a, b, '%.2f' % (b / a) if a else '-'))
PY
rm -f "$out"
