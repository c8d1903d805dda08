"""Compares the layouts the compiler produced (cellphys_layouts --json) with the generator's arithmetic."""
import json
import subprocess
import sys

compiled = json.loads(subprocess.run([sys.argv[1], "--json"], check=True, capture_output=True, text=True).stdout)
declared = json.load(open(sys.argv[2]))
bad = []
for name, d in declared.items():
    c = compiled.get(name)
    if c is None:
        bad.append(f"{name}: declared but not compiled")
        continue
    for key in ("size", "align", "payload"):
        if c[key] != d[key]:
            bad.append(f"{name}.{key}: compiled {c[key]}, descriptor arithmetic {d[key]}")
bad += [f"{n}: compiled but not declared" for n in compiled if n not in declared]
for line in bad:
    print(line)
print(f"{len(declared)} layouts compared, {len(bad)} mismatches")
sys.exit(1 if bad else 0)
