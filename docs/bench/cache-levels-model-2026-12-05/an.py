import json, sys, collections
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith('{')]
by = collections.defaultdict(list)
for r in rows: by[(r['scene'], r['asked'])].append(r)
I = 0.5
def model(b, R0=None):
    N, S, C, D, R = b['record_noise_relmse'], b['sampling_relmse'], b['record_thread_seconds'], b['sampling_thread_seconds'], b['record_rays']
    R0 = 1536
    err = I * N + N * R0 / R + S; t = C * R / R0 + D
    return err, t
print('%-16s %8s %8s %6s | %5s %7s | %6s %6s %6s %6s | %6s %6s' % ('scene','one','two','2/1','N/S','dflt','C1','C2','D1','D2','sec/rec', 'pred2/1'))
for sc in dict.fromkeys(r['scene'] for r in rows):
    one, two, d = by[(sc,1)], by[(sc,2)], by[(sc,0)]
    if not one or not two: continue
    et = lambda L: sum(r['relmse'] * r['wall'] for r in L) / len(L)
    ns = [r['balance']['one_level_record_noise_relmse'] / max(1e-12, r['balance']['one_level_sampling_relmse']) for r in d]
    b1 = one[0]['balance']; b2 = two[0]['balance']
    e1, t1 = model(b1); e2, t2 = model(b2)
    sec = sum(r['secondary'] for r in two) / max(1, sum(r['records'] - r['secondary'] for r in two))
    print('%-16s %8.2e %8.2e %6.2f | %5.1f %7s | %6.1f %6.1f %6.2f %6.2f | %6.2f %6.2f' % (sc, et(one), et(two), et(two)/et(one), sum(ns)/len(ns), ','.join(str(r['levels']) for r in d), b1['record_thread_seconds'], b2['record_thread_seconds'], b1['sampling_thread_seconds'], b2['sampling_thread_seconds'], sec, (e2*t2)/(e1*t1)))
print()
for sc in dict.fromkeys(r['scene'] for r in rows):
    out = []
    for seed in (7, 8):
        o = [r for r in by[(sc,1)] if r['seed'] == seed]; t = [r for r in by[(sc,2)] if r['seed'] == seed]
        if not o or not t: continue
        e1, t1 = model(o[0]['balance']); e2, t2 = model(t[0]['balance'])
        out.append('%.2f (true %.2f)' % (e2*t2/(e1*t1), t[0]['relmse']*t[0]['wall']/(o[0]['relmse']*o[0]['wall'])))
    print('%-16s' % sc, '  '.join(out))
