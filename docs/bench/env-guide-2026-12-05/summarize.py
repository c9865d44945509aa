"""Summarise run.sh's log: per scene, mean relMSE and CPU seconds with the guide and without,
their ratios, error x time, and the mean relMSE between the seeds' images (their noise)."""
import re, sys, collections
runs = collections.defaultdict(lambda: collections.defaultdict(list))
pairs = collections.defaultdict(lambda: collections.defaultdict(list))
for line in open(sys.argv[1]):
    m = re.match(r'(\S+)\s+(guide|off)\s+seed (\d+)\s+relMSE (\S+)\s+cpu\s+(\S+)', line)
    if m:
        runs[m[1]][m[2]].append((float(m[4]), float(m[5])))
    m = re.match(r'(\S+) (guide|off) seeds \S+ relMSE between them (\S+)', line)
    if m:
        pairs[m[1]][m[2]].append(float(m[3]))
print('| scene | relMSE guide / off | CPU s guide / off | relMSE ratio | error x time ratio | seed-to-seed ratio |')
print('|---|---|---|---|---|---|')
for s, r in runs.items():
    e = {k: sum(x[0] for x in v) / len(v) for k, v in r.items()}
    t = {k: sum(x[1] for x in v) / len(v) for k, v in r.items()}
    et = {k: sum(x[0] * x[1] for x in v) / len(v) for k, v in r.items()}
    p = {k: sum(v) / len(v) for k, v in pairs[s].items()}
    print(f"| {s} | {e['guide']:.3g} / {e['off']:.3g} | {t['guide']:.2f} / {t['off']:.2f} | "
          f"{e['guide'] / e['off']:.2f} | {et['guide'] / et['off']:.2f} | {p['guide'] / p['off']:.2f} |")
