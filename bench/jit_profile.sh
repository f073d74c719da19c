#!/bin/bash
# Where a lavapipe shader spends its time, instruction by instruction.
#
# llvmpipe compiles each pipeline to x86 code at run time; perf sees samples
# in it but has no symbols or code to annotate them with. This runs a command
# (one that renders for long enough, e.g. `penumbra render ... --frames 40`),
# samples it with perf after a warm-up, then copies the hottest blocks of
# anonymous executable memory out of the still running process with gdb and
# disassembles them with each instruction's share of the samples.
#
#   bench/jit_profile.sh OUT WARMUP_S RECORD_S COMMAND...
#
# OUT/regions.txt: the hottest regions (one region is usually one pipeline's
# code), OUT/jitN.asm: region N annotated (the first column is the percentage
# of all the process's samples), OUT/blocks.txt: each region's hottest
# straight-line blocks. Reading the code: `lock xadd` is an atomic (its cost
# shows on the next instruction), `vpextrd`/`vpinsrd` runs are a load or store
# done lane by lane, a call to a small out-of-line function with
# vpunpck* shuffles is a texel fetch, and vmovaps to and from (%rsp) are
# spills. Needs perf (linux-perf) and gdb; perf_event_paranoid <= 2 is enough
# to sample one's own process.
set -euo pipefail
if [ $# -lt 4 ]; then
    echo "usage: $0 OUT WARMUP_S RECORD_S COMMAND..." >&2
    exit 2
fi
out=$1 warmup=$2 record=$3
shift 3
for tool in perf gdb objdump python3; do
    command -v "$tool" > /dev/null || { echo "jit_profile: $tool not found" >&2; exit 1; }
done
mkdir -p "$out"
"$@" > "$out/command.txt" 2>&1 &
pid=$!
trap 'kill $pid 2> /dev/null || true' EXIT
sleep "$warmup"
kill -0 $pid 2> /dev/null || { echo "jit_profile: the command ended within the warm-up ($out/command.txt)" >&2; exit 1; }
perf record -q -o "$out/perf.data" -F 1999 -p $pid -- sleep "$record" > /dev/null 2>&1
kill -0 $pid 2> /dev/null || { echo "jit_profile: the command ended while sampled; make it run longer" >&2; exit 1; }
perf report -i "$out/perf.data" --no-children --sort sym 2> /dev/null | grep -v '^#' | grep '%' > "$out/hot.txt"
python3 - "$out" $pid << 'PY'
import re, subprocess, sys
out, pid = sys.argv[1], sys.argv[2]
hot = {}
for line in open(out + '/hot.txt'):
    m = re.search(r'([0-9.]+)%.*\[\.\] 0x([0-9a-f]+)', line)
    if m:
        hot[int(m.group(2), 16)] = float(m.group(1))
regions = []
for line in open('/proc/%s/maps' % pid):
    fields = line.split()
    if 'x' in fields[1] and len(fields) < 6:  # anonymous executable memory: JIT code
        a, b = (int(x, 16) for x in fields[0].split('-'))
        regions.append([a, b, sum(p for addr, p in hot.items() if a <= addr < b)])
regions.sort(key=lambda r: -r[2])
with open(out + '/regions.txt', 'w') as f, open(out + '/blocks.txt', 'w') as fb:
    f.write('JIT code: %.1f%% of the samples\n' % sum(r[2] for r in regions))
    for i, (a, b, share) in enumerate(regions[:4]):
        f.write('region %d: %#x, %d bytes, %.1f%%\n' % (i, a, b - a, share))
        binary = '%s/jit%d.bin' % (out, i)
        subprocess.run(['gdb', '-p', pid, '-batch', '-ex', 'dump binary memory %s %d %d' % (binary, a, b)], capture_output=True)
        asm = subprocess.run(['objdump', '-D', '-b', 'binary', '-mi386:x86-64', '--adjust-vma=%d' % a, binary],
                             capture_output=True, text=True).stdout.split('\n')
        blocks, share_now, start = [], 0.0, None
        with open('%s/jit%d.asm' % (out, i), 'w') as fa:
            for n, line in enumerate(asm):
                m = re.match(r'\s*([0-9a-f]+):', line)
                p = hot.get(int(m.group(1), 16), 0.0) if m else 0.0
                fa.write('%6s %s\n' % ('%5.2f' % p if p else '', line))
                if m:
                    start = n if start is None else start
                    share_now += p
                    if re.search(r'\tj[a-z]+ |\tcall|\tret', line):
                        blocks.append((share_now, start + 1, n + 1))
                        share_now, start = 0.0, None
        blocks.sort(reverse=True)
        fb.write('region %d: %s\n' % (i, ', '.join('%.1f%% at lines %d-%d' % blk for blk in blocks[:12])))
PY
cat "$out/regions.txt" "$out/blocks.txt"
