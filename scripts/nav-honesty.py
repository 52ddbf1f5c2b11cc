#!/usr/bin/env python3
"""Issue 28's honesty runs: a built-in scenario over many seeds (and a correlation time),
synthesised and calibrated with the release binary, each parameter's error against its
reported sigma. Usage: nav-honesty.py SCENARIO TAU_S SEEDS [FIRST_SEED] [--white]
(--white: the site declaring preset "white", the white-noise solve, for comparison).
Prints converged, per parameter RMS z-score, fraction within 3 sigma, RMS error, and the
error's standard deviation against what `spherecal plan` predicts for the same scenario
(issue 28 item 6: within 20 %)."""
import json, os, re, subprocess, sys, tempfile, math

exe = os.environ.get("SPHERECAL") or os.path.join(os.path.dirname(__file__), "..", "target", "release", "spherecal")
scen, tau, seeds = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
first = int(sys.argv[4]) if len(sys.argv) > 4 and not sys.argv[4].startswith("--") else 1
white = "--white" in sys.argv
# --set KEY=VALUE (repeatable): a key of [ins.correlated] (e.g. attitude_sigma_deg=[0,0]).
sets = [a.split("=", 1) for i, a in enumerate(sys.argv) if i > 0 and sys.argv[i - 1] == "--set"]
base = subprocess.run([exe, "synth", "--print-scenario", scen], capture_output=True, text=True, check=True).stdout
names = ["roll", "pitch", "heading", "x", "y", "z"]
z2 = {n: [] for n in names}
err = {n: [] for n in names}
conv = 0
centre_rms = []
work = tempfile.mkdtemp(prefix="nav-honesty-")
for k in range(first, first + seeds):
    t = re.sub(r"(?m)^seed = \d+", f"seed = {k}", base)
    extra = "".join(f"{k} = {v}\n" for k, v in sets)
    t = re.sub(r"(?m)^\[ins\.correlated\]\n", f"[ins.correlated]\ncorrelation_s = {tau}\n{extra}", t)
    sp = os.path.join(work, "s.toml")
    open(sp, "w").write(t)
    out = os.path.join(work, "o")
    subprocess.run(["rm", "-rf", out])
    subprocess.run([exe, "synth", "--scenario", sp, "--out", out], capture_output=True, check=True)
    site = os.path.join(out, "site.toml")
    if white:
        s = open(site).read()
        s = s.split("\n[noise]")[0] + '\n[ins.correlated]\npreset = "white"\n'
        open(site, "w").write(s)
    rep = os.path.join(out, "r.json")
    subprocess.run([exe, "calibrate", "--pcap", f"{out}/lidar.pcap", "--ins", f"{out}/ins.bin",
                    "--site", site, "--report", rep], capture_output=True)
    truth = json.load(open(f"{out}/truth.json"))
    if not os.path.exists(rep):
        continue
    r = json.load(open(rep))
    ok = r["converged"]
    conv += ok
    if r.get("sphere_centre_rms_m") is not None:
        centre_rms.append(r["sphere_centre_rms_m"])
    for n in names:
        g = "boresight_deg" if n in names[:3] else "lever_arm_m"
        e = r[g][n] - truth[g][n]
        s = r["sigma"][g][n]
        err[n].append(e)
        if ok:
            z2[n].append((e / s) if s > 0 else float("inf"))
    print(f"seed {k}: {'converged' if ok else 'refused: ' + str(r.get('reason'))[:90]} "
          + " ".join(f"{n} {err[n][-1]:+.4f}" for n in names), flush=True)
print(f"{scen} tau {tau} s, {seeds} seeds{' (white solve)' if white else ''}: converged {conv}/{seeds}")
if centre_rms:
    cr = sorted(centre_rms)
    print(f"  sphere centre RMS (the passes' fitted centres against the survey): median "
          f"{1e3 * cr[len(cr) // 2]:.1f} mm, {1e3 * cr[0]:.1f}-{1e3 * cr[-1]:.1f} mm (the paper's real survey: 36 mm)")
# The plan's prediction for the scenario (the first seed's file: the noise and model are the
# same for every seed).
t = re.sub(r"(?m)^\[ins\.correlated\]\n", f"[ins.correlated]\ncorrelation_s = {tau}\n" + "".join(f"{k} = {v}\n" for k, v in sets), base)
sp = os.path.join(work, "plan.toml")
open(sp, "w").write(t)
pr = os.path.join(work, "plan.json")
subprocess.run([exe, "plan", "--scenario", sp, "--report", pr], capture_output=True)
pred = json.load(open(pr))["predicted"]["sigma_deg_m"] if os.path.exists(pr) else [None] * 6
for i, n in enumerate(names):
    zs = z2[n]
    rmsz = math.sqrt(sum(z * z for z in zs) / len(zs)) if zs else float("nan")
    w3 = sum(abs(z) <= 3 for z in zs) / len(zs) if zs else float("nan")
    rmse = math.sqrt(sum(e * e for e in err[n]) / len(err[n])) if err[n] else float("nan")
    m = sum(err[n]) / len(err[n]) if err[n] else float("nan")
    sd = math.sqrt(sum((e - m) ** 2 for e in err[n]) / max(len(err[n]) - 1, 1)) if err[n] else float("nan")
    p = pred[i] if not white else None
    vs = f"  sd {sd:.5f} / plan {p:.5f} = {sd / p:.2f}" if p else ""
    print(f"  {n:8s} RMS z {rmsz:5.2f}  within 3 sigma {100*w3:5.1f} %  RMS error {rmse:.5f}{vs}")
