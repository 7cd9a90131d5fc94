#!/usr/bin/env python3
"""RSS of a running service against its factorisation cache bytes while
quadratures of random size churn the cache (docs/BENCHMARKS.md, "Memory under
quadrature churn"). Usage: quadrature_memory.py URL SERVER_PID COUNT"""
import json, random, sys, time, urllib.request
url = sys.argv[1]; pid = int(sys.argv[2]); n = int(sys.argv[3])
def rss():
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"): return int(line.split()[1]) // 1024
def gauge():
    text = urllib.request.urlopen(url + "/metrics").read().decode()
    for line in text.splitlines():
        if line.startswith("bmc_factorisation_cache_bytes"): return float(line.split()[-1]) / 2**20
rng = random.Random(1)
t0 = time.time()
for i in range(n):
    body = {"sample_set": {"kind": "fibonacci", "count": rng.randint(256, 1024)},
            "kernel": {"kind": "squared_exponential", "lengthscale": round(rng.uniform(0.2, 2.0), 4)},
            "density": {"kind": "lambert"}}
    req = urllib.request.Request(url + "/v1/quadratures", json.dumps(body).encode(), {"content-type": "application/json"})
    while True:
        try:
            urllib.request.urlopen(req).read(); break
        except urllib.error.HTTPError as e:
            if e.code == 503: time.sleep(int(e.headers.get("retry-after", "1"))); continue
            raise
    if (i + 1) % 100 == 0:
        print(f"{i+1} quadratures, {time.time()-t0:.0f} s: RSS {rss()} MiB, cache reports {gauge():.0f} MiB", flush=True)
