#!/usr/bin/env python3
"""The per-world tables of RESULTS.md ("Defaults: masked actions, floored advantages"):
reads experiments/masked/<world>/summary.json (written by `fulcrum experiment`) and prints,
per arm, seeds solved, the IQM of steps to 0.9 with its bootstrap interval, the median,
the log-rank p against the baseline with its direction, and Holm's adjustment over the
four empowerment forms of the world. Standard library only."""
import json
import os
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
worlds=[('exp1-tree','500k'),('exp1-wall','500k'),('exp2','3M'),('exp3','3M')]
def st(x):
    if x is None: return '-'
    return f"{x/1e6:.2f}M" if x>=1e6 else f"{x/1e3:.0f}k"
def pt(p):
    return "< 0.001" if p<0.001 else f"{p:.3f}"
for w,b in worlds:
    try: s=json.load(open(os.path.join(ROOT, 'experiments', 'masked', w, 'summary.json')))
    except Exception as e: print(w,e); continue
    comps={c['arm']:c for c in s['comparisons']}
    # Holm over the arms compared with baseline
    fam={'additive','additive-fixed','horizon-potential','first-visit'}
    ps=[(c['log_rank']['p'] if c['log_rank'] else 1.0, c['arm']) for c in s['comparisons'] if c['arm'] in fam]
    ps.sort()
    m=len(ps); holm={}; run=0
    for i,(p,a) in enumerate(ps):
        adj=min(1.0,(m-i)*p); run=max(run,adj); holm[a]=run
    print(f"\n{w} (budget {b})")
    print("| arm | solved | IQM steps to 0.9 (95% CI) | median | log-rank p vs baseline | Holm (4 forms) |")
    print("|---|---|---|---|---|---|")
    for a in s['arms']:
        c=comps.get(a['name'])
        ci=a['iqm_ci']
        iq=f"{st(a['iqm_steps'])} ({st(ci[0])} - {st(ci[1])})" if ci else '-'
        lr = pt(c['log_rank']['p']) if c and c['log_rank'] else '-'
        dirn=''
        if c and c['log_rank']:
            dirn = ' (faster)' if c['log_rank']['observed_a']>c['log_rank']['expected_a'] else ' (slower)'
        h = pt(holm[a['name']]) if a['name'] in holm else '-'
        print(f"| {a['name']} | {a['reached']}/{a['finished']} | {iq} | {st(a['median_steps'])} | {lr}{dirn if c else ''} | {h} |")
