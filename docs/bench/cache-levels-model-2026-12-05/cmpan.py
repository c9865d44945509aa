import json, sys, collections
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith('{')]
bins = list(dict.fromkeys(r['bin'] for r in rows))
by = collections.defaultdict(list)
for r in rows: by[(r['scene'], r['bin'])].append(r)
print('%-16s %28s %28s %6s %6s' % ('scene', 'old: relMSE wall levels', 'new: relMSE wall levels', 'ExT', 'pilot+'))
tot = []
for sc in dict.fromkeys(r['scene'] for r in rows):
    a, b = by[(sc, bins[0])], by[(sc, bins[1])]
    n = min(len(a), len(b)); a, b = a[:n], b[:n]
    if n == 0: continue
    f = lambda L: (sum(r['relmse'] for r in L)/n, sum(r['wall'] for r in L)/n, ''.join(str(r['levels']) for r in L), sum(r['pilot'] for r in L)/n)
    ea, ta, la, pa = f(a); eb, tb, lb, pb = f(b)
    ratio = (eb*tb)/(ea*ta); tot.append(ratio)
    print('%-16s %10.3e %6.2f %8s   %10.3e %6.2f %8s  %6.2f %6.2f' % (sc, ea, ta, la, eb, tb, lb, ratio, pb - pa))
import math
print('geomean', math.exp(sum(math.log(x) for x in tot)/len(tot)))
