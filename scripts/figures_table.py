#!/usr/bin/env python3
"""The "Current figures" table from scripts/figures.sh's raw outputs.

usage: scripts/figures_table.py OUT_DIR HOST DATE COMMIT LEVEL [LEVEL ...]
Prints one Markdown table: figure, value (and spread where the bench gives one), CPU level,
host CPU, date, commit, the command that measured it. Figures whose outputs are missing are
left out.
"""
import json
import os
import re
import sys


def load_json(path):
    try:
        with open(path) as f:
            text = f.read()
    except OSError:
        return None
    # The last JSON object in the file (commands may print other lines first).
    for line in reversed(text.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                return json.loads(line)
            except json.JSONDecodeError:
                break
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return None


def gnu_time(path):
    """(wall seconds, peak RSS MiB) from `/usr/bin/time -v`."""
    try:
        text = open(path).read()
    except OSError:
        return None
    wall = re.search(r"Elapsed \(wall clock\) time.*: (?:(\d+):)?(\d+):([\d.]+)", text)
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    if not wall or not rss:
        return None
    h, m, s = wall.groups()
    return (int(h or 0) * 3600 + int(m) * 60 + float(s), int(rss.group(1)) / 1024)


def fmt(x, digits=3):
    if x is None:
        return "—"
    if abs(x) >= 1e6:
        return f"{x / 1e6:.2f} M"
    if abs(x) >= 1e4:
        return f"{x / 1e3:.0f} k"
    return f"{x:.{digits}g}"


def main():
    out, host, date, commit, *levels = sys.argv[1:]
    rows = []

    def row(figure, value, level, command):
        if command != "same" and not command.startswith("scripts/"):
            command = f"RNERF_CPU_LEVEL={level} {command}"
        rows.append(f"| {figure} | {value} | {level} | {host} | {date} | {commit} | `{command}` |")

    bench_figures = [
        ("training step, samples/s (2 threads)", "train_samples_per_s", ""),
        ("training step, rays/s", "train_rays_per_s", ""),
        ("residual training step, samples/s", "train_residual_samples_per_s", ""),
        ("training step / its kernels' roofline", "train_fraction_of_kernel_bound", ""),
        ("residual step / its kernels' roofline", "train_residual_fraction_of_kernel_bound", ""),
        ("fused MLP fwd+bwd / the level's peak (1 thread)", "mlp_fraction_of_level_peak_1t", ""),
        ("FMA peak, 1 thread", "fma_peak_gflops_1t", " GFLOP/s"),
        ("threshold depth, 200×200 view, bench's model", "render_depth_ms_200", " ms"),
        ("threshold depth, 200×200 view, bench's residual model", "render_depth_ms_200_residual", " ms"),
        ("threshold depth, 640×480 view, bench's model", "render_depth_ms_640x480", " ms"),
        ("threshold depth, 640×480 view, bench's residual model", "render_depth_ms_640x480_residual", " ms"),
    ]
    def timed(level, name, what, command, digits):
        """Wall time and peak RSS of one `/usr/bin/time -v` run, as two rows."""
        t = gnu_time(os.path.join(out, f"{name}_{level}.log.time"))
        if t:
            row(f"{what}, wall", f"{t[0]:.{digits}f} s", level, command)
            row(f"{what}, peak RSS", f"{t[1]:.0f} MiB", level, "same")

    for level in levels:
        b = load_json(os.path.join(out, f"bench_{level}.json"))
        if b:
            spread = b.get("spread", {})
            for name, key, unit in bench_figures:
                if key not in b:
                    continue
                v = fmt(b[key])
                if key in spread:
                    lo, hi = spread[key]
                    v += f" [{fmt(lo)}–{fmt(hi)}]"
                row(name, v + unit, b.get("cpu_level", level), "rnerf bench --json --reps REPS")
        timed(level, "demo", "`rnerf demo` (build excluded)", "rnerf demo", 1)
        table = load_json(os.path.join(out, f"demo_{level}", "table.json"))
        if table:
            for r in table.get("rows", []):
                obj = r.get("object", {})
                if "mae" in obj and r.get("method") in ("dex", "residual"):
                    row(f"`rnerf demo`, {r['method']} object-mask depth MAE", f"{obj['mae']:.3f} m", level, "rnerf demo")
        timed(level, "bg", "dev background, `rnerf train` (1000 × 1024 rays)",
              "rnerf train --data DEV/background --out bg.safetensors", 0)
        e = load_json(os.path.join(out, f"bg_eval_{level}.json"))
        if e:
            row("dev background, test PSNR", f"{e['psnr']:.2f} dB", level, "rnerf eval --model bg.safetensors --data DEV/background --json")
            row("dev background, threshold-depth MAE (crops)", f"{e['mae']:.4f} m", level, "same")
        timed(level, "res", "glass_up Residual-NeRF, `rnerf train` (prior + 1000 steps)",
              "rnerf train --data DEV/glass_up --background bg.safetensors --background-data DEV/background --out res.safetensors", 0)
        e = load_json(os.path.join(out, f"res_eval_{level}.json"))
        if e:
            obj = e.get("regions", {}).get("object", {})
            if "mae" in obj:
                row("glass_up Residual-NeRF, object-mask MAE", f"{obj['mae']:.4f} m", level, "rnerf eval --model res.safetensors --data DEV/glass_up --json")
        b = load_json(os.path.join(out, f"bench_models_{level}.json"))
        if b:
            for key, name in (("render_depth_ms_200", "threshold depth, 200×200, dev background model"),
                              ("render_depth_ms_200_residual", "threshold depth, 200×200, glass_up residual model"),
                              ("render_depth_ms_640x480", "threshold depth, 640×480, dev background model"),
                              ("render_depth_ms_640x480_residual", "threshold depth, 640×480, glass_up residual model")):
                if key in b:
                    row(name, f"{fmt(b[key])} ms", level, "rnerf bench --json --model bg --model res --data DEV/glass_up")
    peers = {}
    for mode in ("eager", "compile"):
        p = load_json(os.path.join(out, f"peer_{mode}.log"))
        if p and "result" in p:
            peers[mode] = p["result"].get("samples_per_s_median")
    for level in levels:
        b = load_json(os.path.join(out, f"bench_{level}.json"))
        if not b or "train_samples_per_s" not in b:
            continue
        for mode, v in peers.items():
            if v:
                row(f"training samples/s ÷ PyTorch peer ({mode})", f"{b['train_samples_per_s'] / v:.1f}×", level,
                    f"scripts/figures.sh with PEER (peer: {fmt(v)} samples/s)")
    print("| figure | value | CPU level | host CPU | date | commit | command |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
