#!/usr/bin/env bash
# Issue 17: the fusion alone on every e2e scene's DOA lines (`ctest -R 'e2e\.'` first), once per
# DOA likelihood (gaussian, outlier_mixture; only fusion.likelihood changed), `eval` against the
# truth; one line per scene and likelihood: RMSE, coverage, id switches, per source. The README's
# and docs/fusion.md's "price without outliers" figures (session 12). Scenes with a pose file
# relative to their site are reported as failed (their sites are not copied with it).
# LIKELIHOODS (default "gaussian outlier_mixture adaptive"): `outlier_mixture` is the fixed e
# (fusion.adaptive_outlier_probability false), `adaptive` the mixture with e estimated per array.
# A name may carry more fusion keys after a colon, numbers only: `outlier_mixture:outlier_probability=0.05`
# or `adaptive:outlier_probability=0.05,outlier_window_doas=200`.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bin=$PWD/${BUILD:-build/release}/dronetrack
for d in ${BUILD:-build/release}/tests/e2e/*/; do
  [[ -f $d/doa.jsonl && -f $d/site.json ]] || continue
  name=$(basename $d)
  for lik in ${LIKELIHOODS:-gaussian outlier_mixture adaptive}; do
    out=${WORK:-build/likelihood-compare}/$name/${lik//[:=,]/_}; mkdir -p $out
    python3 - "$d/site.json" "$out/site.json" "$lik" <<'PY'
import json,sys,os
s=json.load(open(sys.argv[1])); f=s.setdefault("fusion",{})
kind,_,extra=sys.argv[3].partition(":")
f["likelihood"]="outlier_mixture" if kind=="adaptive" else kind
f["adaptive_outlier_probability"]=kind=="adaptive"
for kv in filter(None,extra.split(",")):
    k,v=kv.split("="); f[k]=float(v)
base=os.path.dirname(os.path.abspath(sys.argv[1]))
# keep recording paths resolvable
for a in s.get("arrays",[]):
    r=a.get("recording")
    if isinstance(r,str) and not os.path.isabs(r): a["recording"]=os.path.join(base,r)
json.dump(s,open(sys.argv[2],"w"))
PY
    $bin --log-level warn replay $out/site.json --doa-in $d/doa.jsonl --tracks-out $out/tracks.jsonl >/dev/null 2>$out/err || { echo "$name $lik replay failed: $(tail -1 $out/err)"; continue; }
    $bin --log-level warn eval --truth $d/truth.json --tracks $out/tracks.jsonl --json $out/eval.json >/dev/null 2>>$out/err || { echo "$name $lik eval failed: $(tail -1 $out/err)"; continue; }
    python3 - "$out/eval.json" "$name" "$lik" <<'PY'
import json,sys
e=json.load(open(sys.argv[1]))
def g(x,*k):
    for kk in k:
        if isinstance(x,dict) and kk in x: x=x[kk]
        elif isinstance(x,list) and isinstance(kk,int) and kk<len(x): x=x[kk]
        else: return None
    return x
srcs=e.get("sources",[])
per=" ".join("%.3f/%.1f%%"%(g(s,"position","rmse_3d_m") or float('nan'),100*(s.get("coverage") or 0)) for s in srcs)
print("%-28s %-16s rmse %.3f cov %.1f%% idsw %s  per-source %s"%(sys.argv[2],sys.argv[3],g(e,"position","rmse_3d_m") or float('nan'),100*(e.get("coverage") or 0),e.get("id_switches"),per))
PY
  done
done
