#!/usr/bin/env python3
# DOA coverage per source and array over ALL frames (not only the audible ones): the share of
# frames with a DOA within 3 deg of the truth direction at that frame's time. The README's "Drone
# or not" table's DOA-coverage column (session 12). Usage:
#   scripts/doa-coverage.py DIR RUN     reads DIR/truth.json and DIR/RUN/doa.jsonl
# e.g. after `ctest -R e2e.mixed_site`: mkdir -p /tmp/m/run; ln -s
# build/release/tests/e2e/mixed_site/{truth.json} /tmp/m; ln -s .../doa.jsonl /tmp/m/run
import json, sys, math, collections
d=sys.argv[1]; run=sys.argv[2]
t=json.load(open(f'{d}/truth.json'))
doas=collections.defaultdict(list)
for line in open(f'{d}/{run}/doa.jsonl'):
    r=json.loads(line); doas[r['array']].append((r['t'],r['direction']))
rate=t['rate_hz']
out=[]
for s in t['sources']:
    row=[]
    for a in sorted(t['arrays']):
        dirs=s['doa'][a]['direction']
        frames=collections.defaultdict(bool)
        for (time,v) in doas[a]:
            k=int(round(time*rate)); 
            if k>=len(dirs): continue
            u=dirs[k]; c=sum(x*y for x,y in zip(u,v))
            if c>=math.cos(math.radians(3)): frames[round((time-0.085)/0.05)]=True
        n=int(t['duration_s']/0.05)
        row.append(f"{a} {100.0*sum(frames.values())/n:5.1f}")
    out.append(s['id']+": "+"  ".join(row))
print("\n".join(out))
