#!/usr/bin/python3
"""Writes the benchmark report from the files of scripts/run_benchmarks.

Usage: report.py RESULTS_DIR. Reads s1.csv, s1_pairs.csv, s2.csv, s2_state.csv,
s2_auto.csv, s2_rest.csv, s3.csv, baselines.csv, forces.csv, memory.csv, registration.txt,
registration_zoo*.csv, registered_objects.csv, add_object.csv, reset_latency.csv, threads.csv,
self_collision.csv and distance.csv there; writes s1.md, s2.md, threads.md, self_collision.md,
s3.md, forces.md, memory.md, registration.md, registration_zoo.md, registered_objects.md, distance.md,
add_object.md, summary.md (headline figures and the targets, met or not) and the plots s1_time_vs_points.png, s2_error_vs_time.png,
registration_error_vs_time.png, registration_zoo_error_vs_time.png,
add_object_time_vs_points.png. When RESULTS_DIR is the package's bench/results, it also
writes docs/benchmarks.md (bench/benchmarks_intro.md, then those tables and plots, and
latency.md of make latency if there) and the headline table between README.md's results
markers, if it has them.
Run by Debian's python3 (python3-matplotlib).
"""
import csv
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)

OURS = "deformation_update"
OUR_VARIANTS = ("deformation_update", "exact_refit", "full_refit")
PEERS = ("fcl_aabb", "fcl_obbrss", "bullet_dbvt", "pcl_kdtree")

WHAT_S1_METHODS_DO = """\
Every method answers the same query on the same deforming points, in the same process,
each step: which point pairs (one point of each ball) are closer than the contact distance.
The run stops if any method finds other pairs than `deformation_update`.

| method | what one step does | volumes updated counts |
|---|---|---|
| deformation_update | our sphere trees; spheres from the shape-matching matrices, computed only where the query descends; query to the leaves | spheres computed |
| exact_refit | our sphere trees; smallest enclosing sphere of the current points of each visited node | spheres computed |
| full_refit | our sphere trees; every node refitted bottom-up, then the same query | spheres refitted (all) |
| fcl_aabb | FCL BVHModel<AABB> point cloud per ball: beginUpdateModel / updateSubModel / endUpdateModel (bottom-up refit), then a descent over FCL's nodes with FCL's AABB distance test | BV nodes refitted (all) |
| fcl_obbrss | the same with BVHModel<OBBRSS>, refitted top-down (FCL 0.7.0's bottom-up OBBRSS refit leaves boxes that miss points); FCL's OBB overlap test on boxes grown by half the contact distance | BV nodes refitted (all) |
| bullet_dbvt | a btDbvt per ball, a leaf per point (its box grown by half the contact distance); leaves updated as btDbvtBroadphase does (reinserted when they leave their fattened box, one optimizeIncremental pass), then collideTT | leaves reinserted |
| pcl_kdtree | KdTreeFLANN over ball b rebuilt, a radius search around every point of ball a inside b's box grown by the contact distance | points indexed |

FCL's own collide() and distance() take triangle models only, so the FCL query is a
descent over FCL's bounding volumes written in the bench. Every peer confirms its candidate
pairs with the exact distance in double precision.
"""


def read(results, name):
    with open(os.path.join(results, name), newline="") as f:
        return list(csv.DictReader(f))


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write(results, name, text):
    with open(os.path.join(results, name), "w") as f:
        f.write(text)


NEAR_MISS_M = 0.005  # the contact distance of the near-miss case, and of rows without one
DENSE_M = 0.05


def s1_case_name(distance):
    return "near miss" if distance == NEAR_MISS_M else "dense contact"


def contact_distance(row):
    return float(row.get("contact_distance_m") or NEAR_MISS_M)


def s1_case_text(distance, rows, pairs):
    """One S1 case (one contact distance): the methods at every size, and the pairs found."""
    sizes = sorted({int(r["points"]) for r in rows})
    ours = {int(r["points"]): float(r["collision_ms"]) for r in rows if r["method"] == OURS}
    body = [(int(r["points"]), r["method"], r["spheres_updated"], f"{float(r['collision_ms']):.3f}",
             f"{float(r['ratio_to_full_refit']):.4f}",
             f"{float(r['collision_ms']) / ours[int(r['points'])]:.1f}") for r in rows]
    text = f"## {s1_case_name(distance).capitalize()}: contact distance {distance * 1000:g} mm\n\n"
    text += table(["points in all", "method", "volumes updated/step", "collision ms", "/ full refit",
                   "/ deformation_update"], body)
    text += "\nPoint pairs closer than the contact distance, found identically by all methods:\n\n"
    text += table(["points in all", "methods agreeing", "point pairs/step"],
                  [(p, pairs[p]["methods"], pairs[p]["point_pairs_per_step"]) for p in sizes])
    return text + "\n"


def best_peer(ms, distance, points, methods):
    peers = [m for m in methods if m in PEERS and (distance, points, m) in ms]
    return min(peers, key=lambda m: ms[(distance, points, m)])


def s1_report(results):
    rows = read(results, "s1.csv")
    pairs = {(contact_distance(r), int(r["points"])): r for r in read(results, "s1_pairs.csv")}
    distances = sorted({contact_distance(r) for r in rows})
    sizes = sorted({int(r["points"]) for r in rows})
    ms = {(contact_distance(r), int(r["points"]), r["method"]): float(r["collision_ms"])
          for r in rows}
    methods = [m for m in OUR_VARIANTS + PEERS if (distances[0], sizes[0], m) in ms]
    steps = next(iter(pairs.values()))["steps"]
    text = "# S1: two deforming balls, collision stage per step\n\n"
    text += ("Two quadratic shape-matching balls (radius 0.5 m, 4 clusters each) pressed 2 cm into "
             "each other and released from a bend; mean of "
             f"{steps} steps per size. Two cases: a near miss (contact distance 5 mm, a few point "
             "pairs per step) and dense contact (5 cm, thousands of point pairs per step). Times "
             "in ms per step; the baseline is `full_refit` in the same run.\n\n")
    summary_rows = []
    for distance in distances:
        for points in sizes:
            if (distance, points, OURS) not in ms:
                continue
            peer = best_peer(ms, distance, points, methods)
            summary_rows.append((s1_case_name(distance), points, f"{ms[(distance, points, OURS)]:.3f}",
                                 peer, f"{ms[(distance, points, peer)]:.3f}",
                                 f"{ms[(distance, points, peer)] / ms[(distance, points, OURS)]:.1f}"))
    text += table(["case", "points in all", f"{OURS} ms", "best peer", "best peer ms",
                   "best peer / ours"], summary_rows) + "\n"
    for distance in distances:
        text += s1_case_text(distance, [r for r in rows if contact_distance(r) == distance],
                             {p: r for (d, p), r in pairs.items() if d == distance})
    text += WHAT_S1_METHODS_DO
    write(results, "s1.md", text)

    fig, axes = plt.subplots(1, len(distances), figsize=(7 * len(distances), 5), squeeze=False)
    for ax, distance in zip(axes[0], distances):
        shown = [p for p in sizes if (distance, p, OURS) in ms]
        for m in methods:
            ax.loglog(shown, [ms[(distance, p, m)] for p in shown], marker="o", label=m,
                      linewidth=2.5 if m == OURS else 1.2)
        ax.set_xlabel("points in both objects")
        ax.set_ylabel("collision stage, ms per step")
        ax.set_title(f"S1 {s1_case_name(distance)} ({distance * 1000:g} mm): update + query")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(results, "s1_time_vs_points.png"), dpi=110)
    plt.close(fig)
    return sizes, ms, methods


def baseline(results, scene):
    return next(float(r["ms"]) for r in read(results, "baselines.csv") if r["scene"] == scene)


def finest_query_levels(rows):
    """The levels that run the finest level's query: its contacts, no error against it."""
    finest = rows[-1]
    return [r for r in rows if r["contacts"] == finest["contacts"]
            and float(r["coverage_error_m"]) == 0.0 and float(r["rms_error_rel"]) == 0.0]


def run_noise(rows):
    """The largest deviation from their mean of the totals of the levels that run the finest
    query, relative to it: the noise of one run (None if only the finest runs it)."""
    same = [float(r["total_ms"]) for r in finest_query_levels(rows)]
    if len(same) < 2:
        return None
    mean = sum(same) / len(same)
    return max(abs(t - mean) for t in same) / mean


def pareto_levels(rows):
    """The levels no other level beats in both time (detection + response) and RMS error."""
    def beats(s, r):
        ts, tr = float(s["total_ms"]), float(r["total_ms"])
        es, er = float(s["rms_error_rel"]), float(r["rms_error_rel"])
        return ts <= tr and es <= er and (ts < tr or es < er)
    return [r["level"] for r in rows if not any(beats(s, r) for s in rows)]


def distinct_levels(rows):
    """The coarse levels whose query differs from the finest's, and the finest."""
    same = {r["level"] for r in finest_query_levels(rows)}
    return [r for r in rows[:-1] if r["level"] not in same] + [rows[-1]]


def s2_rest_target(rest):
    """The rest target, at every level the rest runs cover (0, each object one sphere, to the
    finest)."""
    fastest = max(rest, key=lambda r: float(r["late_largest_speed_mps"]))
    cycles, late = rest[0]["cycles"], rest[0]["late_cycles"]
    return (f"S2: mean point speed < 5 mm/s after {cycles} cycles at each level (the dropped "
            f"pile), at every one of the last {late}",
            f"at most {1000 * float(fastest['late_largest_speed_mps']):.1f} mm/s (level "
            f"{fastest['level']}), levels {rest[0]['level']} to {rest[-1]['level']}",
            "**met**" if float(fastest["late_largest_speed_mps"]) < 0.005 else "**not met**")


def s2_level_targets(rows, rest):
    """The target rows of S2's levels (issue: level of detail that pays)."""
    finest = rows[-1]
    finest_total = float(finest["total_ms"])
    noise = run_noise(rows)
    same = finest_query_levels(rows)
    distinct = distinct_levels(rows)
    coarse = distinct[:-1]
    by_level = {r["level"]: r for r in rows}
    level2 = float(by_level["2"]["total_ms"]) / finest_total if "2" in by_level else None
    dearest = max(coarse, key=lambda r: float(r["total_ms"])) if coarse else None
    tolerance = noise if noise is not None else 0.0
    falls = [(a["level"], b["level"]) for a, b in zip(distinct, distinct[1:])
             if float(b["total_ms"]) < float(a["total_ms"]) * (1.0 - tolerance)]
    front = pareto_levels(distinct)
    noise_text = (f"{100 * noise:.0f}%, the spread of the levels that run the finest query"
                  if noise is not None else "not measured (no level repeats the finest query)")
    return [
        ("S2 level 2: detection + response <= 0.3 x the finest level's",
         f"{float(by_level['2']['total_ms']):.2f} / {finest_total:.2f} ms = {level2:.2f}"
         if level2 is not None else "no level 2", "**met**" if level2 is not None and level2 <= 0.3
         else "**not met**"),
        ("S2: every level below the finest cheaper than the finest",
         (f"dearest coarse level {dearest['level']}: {float(dearest['total_ms']) / finest_total:.2f} "
          f"of the finest" if dearest else "no coarse level") +
         (f"; levels {same[0]['level']} to {finest['level']} run the finest query"
          if len(same) > 1 else ""),
         "**met**" if dearest and float(dearest["total_ms"]) < finest_total else "**not met**"),
        ("S2: time grows with the level, within the run's noise",
         f"noise {noise_text}; " + ("no level costs less than the one below it" if not falls else
                                    "cheaper than the level below: " +
                                    ", ".join(f"{b} after {a}" for a, b in falls)),
         "**met**" if not falls else "**not met**"),
        ("S2: the Pareto front of (time, RMS error) holds >= 4 levels",
         f"levels {', '.join(front)}", "**met**" if len(front) >= 4 else "**not met**"),
        s2_rest_target(rest),
    ]


def s2_report(results):
    rows = read(results, "s2.csv")
    rest = read(results, "s2_rest.csv")
    state = read(results, "s2_state.csv")[0]
    base = baseline(results, "s2")
    text = "# S2: the pile at every level\n\n"
    text += (f"300 soft objects ({state['soft_points']} points in them, plus the box), settled "
             f"for {state['settle_cycles']} cycles at the finest level, then "
             f"{state['cycles_per_level']} cycles at each level from that same state; means over "
             f"those cycles. Baseline: a full bottom-up refit of every soft object's hierarchy on "
             f"the settled state, {base:.3f} ms, in the same run.\n\n"
             "Error against the finest level: coverage, the largest distance from a contact at "
             "the finest level to the nearest contact of the same object pair at this level, "
             "both on the settled state; RMS, the deviation of all soft points from the "
             f"finest-level run after the {state['cycles_per_level']} cycles, over the mean object "
             f"diameter ({float(state['mean_diameter_m']):.4f} m); deepest and mean depth, how "
             "far point pairs of two soft objects lie inside half the contact distance (where the "
             "response puts touching objects) after the cycles, over the finest level's contacts. "
             "Whole cycle: shape matching, detection and response. Mean point speed when settled "
             f"{float(state['mean_point_speed_mps']):.3f} m/s; the speed after each level's cycles "
             "is in the table (a switch starts from the coarse spheres' overlaps, which the "
             "response clears by moving objects apart; the pile settles again from there: see "
             "Rest below).\n\n")
    body = [(r["level"], f"{float(r['contacts']):.0f}", f"{float(r['detection_ms']):.2f}",
             f"{float(r['response_ms']):.2f}", f"{float(r['total_ms']):.2f}",
             f"{float(r['total_ms']) / base:.2f}", f"{float(r['whole_cycle_ms']):.2f}",
             f"{float(r['coverage_error_m']):.4f}", f"{float(r['rms_error_rel']):.3f}",
             f"{float(r['speed_after_mps']):.3f}", f"{float(r['deepest_m']):.4f}",
             f"{float(r['mean_depth_m']):.5f}") for r in rows]
    text += table(["level", "contacts", "detection ms", "response ms", "total ms", "total / baseline",
                   "whole cycle ms", "coverage error m", "RMS error / diameter",
                   "mean point speed after, m/s", "deepest m", "mean depth m"], body)
    same = finest_query_levels(rows)
    if len(same) > 1:
        totals = [float(r["total_ms"]) for r in same]
        text += (f"\nLevels {same[0]['level']} to {same[-1]['level']} run the finest level's query "
                 "(the same contacts and states; where every soft object's hierarchy has ended, "
                 "the box meets it at its own leaves): their detection + response, "
                 f"{min(totals):.2f} to {max(totals):.2f} ms, is this run's noise, "
                 f"{100 * run_noise(rows):.0f}% of their mean at most.\n")
    text += s2_rest_text(rest)
    text += "\n## Targets\n\n" + table(["target", "measured", "verdict"],
                                         s2_level_targets(rows, rest))
    text += s2_auto_text(read(results, "s2_auto.csv")[0])
    write(results, "s2.md", text)

    # One point per distinct query: the levels that run the finest query are drawn as the
    # finest level's point, their spread of times as its bar (the run's noise).
    plotted = distinct_levels(rows)
    total = [float(r["total_ms"]) for r in plotted]
    whole = [float(r["whole_cycle_ms"]) for r in plotted]
    same_total = [float(r["total_ms"]) for r in same]
    same_whole = [float(r["whole_cycle_ms"]) for r in same]
    finest_label = (f"{same[0]['level']}-{same[-1]['level']}" if len(same) > 1
                    else plotted[-1]["level"])
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.5))
    for ax, column, label in ((axes[0], "coverage_error_m", "contact coverage error, m"),
                              (axes[1], "rms_error_rel", f"RMS deviation after {state['cycles_per_level']} cycles / diameter"),
                              (axes[2], "deepest_m", "deepest point pair inside half the contact distance, m")):
        values = [float(r[column]) for r in plotted]
        ax.plot(total, values, marker="o", label="detection + response")
        ax.plot(whole, values, marker="x", linestyle="--", label="whole cycle")
        for times, color in ((same_total, "C0"), (same_whole, "C1")):
            if len(times) > 1:
                ax.hlines(values[-1], min(times), max(times), colors=color, linewidth=4, alpha=0.4)
        for r, x, y in zip(plotted, total, values):
            name = finest_label if r is plotted[-1] else r["level"]
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
        ax.legend(fontsize=8)
        ax.set_xlabel("ms per cycle")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    fig.suptitle("S2: error against the finest level, one point per level (levels that run the "
                 "finest query: one point, their spread of times as a bar)")
    fig.tight_layout()
    fig.savefig(os.path.join(results, "s2_error_vs_time.png"), dpi=110)
    plt.close(fig)
    return rows


def s2_rest_text(rest):
    """The rest runs: the pile dropped at each level, its speed late in the run, its depths."""
    text = (f"\n## Rest\n\nThe pile dropped and run at each level for {rest[0]['cycles']} cycles "
            f"(level 0: each object one sphere); the mean point speed over the last "
            f"{rest[0]['late_cycles']} cycles (their mean and their largest) and after the last, "
            "and the end state's depths as above.\n\n")
    return text + table(
        ["level", "mean speed m/s", "largest m/s", "after the last m/s", "deepest m", "mean depth m"],
        [(r["level"], f"{float(r['late_mean_speed_mps']):.4f}",
          f"{float(r['late_largest_speed_mps']):.4f}", f"{float(r['end_speed_mps']):.4f}",
          f"{float(r['deepest_m']):.4f}", f"{float(r['mean_depth_m']):.5f}") for r in rest])


def auto_most_run_level(auto):
    """The level of most cycles of the auto run (cycles_per_level: "level:cycles;...")."""
    pairs = [tuple(map(int, p.split(":"))) for p in auto["cycles_per_level"].split(";")]
    return max(pairs, key=lambda p: p[1])[0]


def s2_auto_text(auto):
    """The `level: auto` run of S2: the budget, the share within it, the levels picked."""
    text = (f"\n## level: auto\n\n{auto['cycles']} cycles with `Scene::setCycleBudget` from the "
            "same settled state, the budget half the finest level's detection + response "
            f"({float(auto['finest_total_ms']):.2f} ms) in this run; the first cycles climb from "
            "level 0, one level every two cycles.\n\n")
    return text + table(
        ["budget ms", "cycles within budget", f"after the first {auto['climb_cycles']}",
         "levels min / mean / max", "most run level", "cycles per level",
         "mean detection + response ms"],
        [(f"{float(auto['budget_ms']):.2f}", f"{100 * float(auto['within_budget_share']):.1f}%",
          f"{100 * float(auto['within_budget_share_after_climb']):.1f}%",
          f"{auto['level_min']} / {float(auto['level_mean']):.2f} / {auto['level_max']}",
          auto_most_run_level(auto), auto["cycles_per_level"].replace(";", ", "),
          f"{float(auto['mean_total_ms']):.2f}")])


def s3_report(results):
    rows = read(results, "s3.csv")
    base = baseline(results, "s3")
    text = "# S3: three objects, the cycle stage by stage\n\n"
    text += (f"A soft ball and a soft bar on a floor (19k points), finest level. Baseline: a full "
             f"bottom-up refit of the soft objects' hierarchies, {base:.3f} ms, in the same run. "
             "The conversion writes every object's points into a new PointCloud2, as the node "
             "publishes them; the whole cycle is timed around Scene::cycle and the conversion.\n\n")
    text += table(["stage", "ms", "/ baseline"],
                  [(r["stage"], f"{float(r['ms']):.3f}", f"{float(r['ms']) / base:.3f}") for r in rows])
    write(results, "s3.md", text)
    return {r["stage"]: float(r["ms"]) for r in rows}


def forces_report(results):
    """forces.md from forces.csv, and its rows; None if the run has no forces.csv."""
    if not os.path.exists(os.path.join(results, "forces.csv")):
        return None
    rows = read(results, "forces.csv")
    text = "# Contact forces: what they add to a cycle\n\n"
    text += ("Each scene built twice, contact_forces on and off, settled 150 cycles and run in "
             "turns of a tenth of the cycles; with forces, each cycle also summarises the pairs "
             "and takes every kinematic object's wrench, as the node does for its subscribers. "
             "The whole cycle, shape matching included.\n\n")
    text += table(["scene", "level", "cycles", "with forces ms", "without ms", "ratio"],
                  [(r["scene"], r["level"], r["cycles"], f"{float(r['with_forces_ms']):.4f}",
                    f"{float(r['without_forces_ms']):.4f}", f"{float(r['ratio']):.3f}")
                   for r in rows])
    write(results, "forces.md", text)
    return rows


def forces_targets(forces):
    """The forces' target rows: at most 10% more whole-cycle time."""
    return [(f"Contact forces, {r['scene']}: whole cycle at most 1.10x the cycle without",
             f"{float(r['with_forces_ms']):.4f} / {float(r['without_forces_ms']):.4f} ms = "
             f"{float(r['ratio']):.3f}x",
             "**met**" if float(r["ratio"]) <= 1.10 else "**not met**") for r in forces or []]


def memory_report(results):
    rows = read(results, "memory.csv")
    text = "# Memory: peak resident memory per scene\n\n"
    text += ("Each scene in its own process, built and run for 150 cycles (two_objects with 160k "
             "points, S1's largest size). Bytes per point: the growth of the peak resident memory "
             "over the process before the scene, over all points of the scene (the static box "
             "and floor included).\n\n")
    text += table(["scene", "points", "peak MB", "before the scene MB", "bytes per point"],
                  [(r["scene"], r["points"], f"{int(r['peak_rss_bytes']) / 1e6:.1f}",
                    f"{int(r['rss_before_bytes']) / 1e6:.1f}", r["bytes_per_point"]) for r in rows])
    write(results, "memory.md", text)


REGISTRATION_LINE = re.compile(
    r"method (?P<method>\S+)(?P<truth> cloud truth)? points (?P<points>\d+) frames (?P<frames>\d+) "
    r"mode (?P<mode>\S+) clusters (?P<clusters>\d+) (?:iterations (?P<iterations>\d+)|static) "
    r"cloud_points (?P<cloud_points>\d+) model_points \d+ \| seen mean (?P<seen>[\d.]+) max [\d.]+ "
    r"off surface (?P<seen_off>[\d.]+) mm \| hidden mean (?P<hidden>[\d.]+) max [\d.]+ "
    r"off surface (?P<hidden_off>[\d.]+) mm \| registration (?P<ms>[\d.]+) ms \(worst (?P<worst_ms>[\d.]+)\)"
    r".*contacts: coverage (?P<coverage>[\d.]+) mm .*missed (?P<missed>\d+) and spurious \d+ "
    r"of (?P<touched>\d+) jaw-frames")
# config/camera_gripper.yaml's rounds and cloud points, which run_benchmarks' comparison runs use.
REGISTRATION_DEFAULTS = ("5", "2000")


def registration_kind(row, sweep_seen):
    """What one line of registration.txt measures. A line of ours does not say whether the
    jaws' points were kept: run_benchmarks repeats one setting of its sweep for that alone,
    after the sweep, so a repeated setting is the run that keeps them."""
    if row["method"] == "pcl_icp":
        return "pcl_icp", "PCL rigid ICP, whole object"
    if row["method"] == "pcl_icp_clusters":
        return "pcl_icp_clusters", "PCL rigid ICP, per cluster"
    if row["method"] == "model_limit":
        return "limit", f"the model's best fit to the truth, {row['mode']} (bound)"
    if row["method"] != "ours":
        return row["method"], row["method"]
    if not row["iterations"]:
        return "rest", "rest model left in place (bound)"
    if row["truth"]:
        return "truth", "ours, the seen ground truth as the cloud"
    setting = (row["iterations"], row["cloud_points"])
    if setting in sweep_seen:
        return "jaws_kept", "ours, the jaws' points kept"
    sweep_seen.add(setting)
    defaults = " (as config/camera_gripper.yaml)" if setting == REGISTRATION_DEFAULTS else ""
    rounds = "1 round" if setting[0] == "1" else f"{setting[0]} rounds"
    return "sweep", f"ours, {rounds}, {setting[1]} cloud points{defaults}"


def read_registration(results):
    """The lines of bench_registration in registration.txt, each with its kind and label;
    none if the file is not there."""
    path = os.path.join(results, "registration.txt")
    if not os.path.exists(path):
        return []
    with open(path) as f:
        rows = [m.groupdict() for m in map(REGISTRATION_LINE.search, f) if m]
    sweep_seen = set()
    for r in rows:
        r["kind"], r["label"] = registration_kind(r, sweep_seen)
    return rows


def registration_defaults(rows):
    """Ours at config/camera_gripper.yaml's settings (None if not run)."""
    return next((r for r in rows if r["kind"] == "sweep"
                 and (r["iterations"], r["cloud_points"]) == REGISTRATION_DEFAULTS), None)


def registration_report(results, rows):
    """registration.md, every line of registration.txt, and its plot."""
    first = rows[0]
    text = "# Registration of depth-camera clouds\n\n"
    text += (f"`bench_registration` registers the camera_gripper sponge ({first['points']} model "
             f"points, {first['mode']} shape matching, {first['clusters']} clusters) to "
             f"{first['frames']} clouds of its virtual depth camera over one squeeze, bend and "
             "release, and scores every model point against the ground truth of the same material "
             "point, on the side the camera sees and on the hidden side. Errors in mm, means over "
             "the clouds: the mean error, and its part off the surface (along the true surface "
             "normal; the rest is a slide along the surface). Time: the registration per cloud, "
             "mean and worst. Contacts: the registered model and the two jaws in a scene of their "
             "own against the same scene given the ground truth; per jaw and frame, the largest "
             "distance from a true contact to the nearest of the model's, mean over the "
             "jaw-frames that touch in truth, and how many of those the model missed.\n\n"
             "Bounds: the rest model left in place, and each cluster's least-squares fit to the "
             "ground truth of all its points, which no registration can beat. Ours: "
             "`Scene::registerCloud` with the jaws posed before each cloud, as in the node, over "
             "the rounds and the cloud points kept per cloud; given the ground truth's seen "
             "points as its cloud (no noise, outliers or holes); and keeping the cloud's points "
             "near the jaws. PCL's rigid ICP on the same thinned clouds and rounds: the cloud "
             "aligned to the whole rest model, or to each cluster alone.\n\n")
    text += table(["run", "seen", "seen, off surface", "hidden", "hidden, off surface",
                   "ms per cloud (worst)", "contact coverage mm", "jaw-frames missed"],
                  [(r["label"], r["seen"], r["seen_off"], r["hidden"], r["hidden_off"],
                    "-" if r["kind"] in ("rest", "limit") else f"{r['ms']} ({r['worst_ms']})",
                    r["coverage"], f"{r['missed']} of {r['touched']}") for r in rows])
    write(results, "registration.md", text)
    registration_plot(results, rows)


def registration_plot(results, rows):
    """Error against time per cloud: ours over the work per cloud (one point per rounds x
    cloud points), the other runs of ours and PCL's whole-object ICP as points of their own,
    the bounds as lines. PCL's per-cluster ICP is left out: its error is off the scale."""
    points = {"pcl_icp": ("grey", "PCL rigid ICP"), "truth": ("C2", "ours given the seen truth"),
              "jaws_kept": ("C5", "ours keeping the jaws' points")}
    sweep = [r for r in rows if r["kind"] == "sweep"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.5), sharey=True)
    for ax, side in ((axes[0], "seen"), (axes[1], "hidden")):
        for key, style, label in ((side, "o", "material point"), (side + "_off", "s", "off the surface")):
            ax.plot([float(r["ms"]) for r in sweep], [float(r[key]) for r in sweep], style,
                    label=f"ours, {label}")
            for r in sweep:
                ax.annotate(f"{r['iterations']}x{r['cloud_points']}", (float(r["ms"]), float(r[key])),
                            textcoords="offset points", xytext=(3, 3), fontsize=6)
            color = "C3" if key == side else "C4"
            for r in rows:
                if r["kind"] in points:
                    point_color, name = points[r["kind"]]
                    ax.plot(float(r["ms"]), float(r[key]), style, color=point_color,
                            label=f"{name}, {label}")
                if r["kind"] == "rest":
                    ax.axhline(float(r[key]), linestyle="--", linewidth=0.8, color=color,
                               label=f"rest model left in place, {label}")
                if r["kind"] == "limit" and r["mode"] == "linear":
                    ax.axhline(float(r[key]), linestyle=":", linewidth=0.8, color=color,
                               label=f"the model's best fit to the truth, {label}")
        ax.set_xscale("log")
        ax.set_xlabel("registration, ms per cloud (rounds x cloud points)")
        ax.set_ylabel(f"{side} side: mean error, mm")
        ax.set_title(f"{side} side")
        ax.grid(True, alpha=0.3)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="lower center", ncol=3, fontsize=7)
    fig.suptitle("Registration of the camera_gripper sponge: error against time per cloud")
    fig.tight_layout(rect=(0, 0.17, 1, 1))
    fig.savefig(os.path.join(results, "registration_error_vs_time.png"), dpi=110)
    plt.close(fig)

ZOO_BOUNDS = (("truth", "registration_zoo_truth.csv"), ("model_limit", "registration_zoo_model_limit.csv"),
              ("seen_limit", "registration_zoo_seen_limit.csv"))


def read_zoo(results):
    """bench_registration_zoo's runs: ours (None if not run), then the bounds by case."""
    path = os.path.join(results, "registration_zoo.csv")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        rows = list(csv.DictReader(f))
    for key, name in ZOO_BOUNDS:
        bound = os.path.join(results, name)
        if not os.path.exists(bound):
            continue
        with open(bound) as f:
            by_case = {(r["shape"], r["deformation"]): r for r in csv.DictReader(f)}
        for r in rows:
            r[key] = by_case.get((r["shape"], r["deformation"]))
    return rows


def zoo_pair(row, seen, hidden):
    return f"{float(row[seen]):.2f} / {float(row[hidden]):.2f}" if row else "-"


def zoo_targets(rows):
    """How many cases meet each of issue 58's targets for the zoo."""
    def count(test):
        return f"{sum(1 for r in rows if test(r))} of {len(rows)}"
    rested = lambda r, side: float(r[f"rested_{side}_mm"])  # noqa: E731
    return table(["target", "cases met"], [
        ("deformation recovered >= 85% seen, >= 70% hidden",
         count(lambda r: float(r["recovered_seen"]) >= 0.85 and float(r["recovered_hidden"]) >= 0.7)),
        ("mean error <= 2 mm seen, <= 4 mm hidden",
         count(lambda r: rested(r, "seen") <= 2 and rested(r, "hidden") <= 4)),
        ("after the rest at most half the error at the end of the motion",
         count(lambda r: rested(r, "seen") <= 0.5 * float(r["end_seen_mm"]))),
        ("registration <= 3 ms per cloud", count(lambda r: float(r["ms_per_cloud"]) <= 3))])


def zoo_estimates(rows):
    """The registration's estimate of its surface error (SurfaceError) against the truth."""
    def covered(side):
        return sum(1 for r in rows
                   if float(r[f"estimate_{side}_mm"]) >= float(r[f"rested_{side}_off_mm"]))
    text = ("The registration's own estimate of its error (`SurfaceError`, in `~stats` and on "
            "contacts) against the model's mean distance from the true surface after the rest, "
            f"mm, seen / hidden. Covered: {covered('seen')} of {len(rows)} seen, "
            f"{covered('hidden')} of {len(rows)} hidden.\n\n")
    return text + table(["shape", "deformation", "surface error", "estimate"],
                        [(r["shape"], r["deformation"],
                          zoo_pair(r, "rested_seen_off_mm", "rested_hidden_off_mm"),
                          zoo_pair(r, "estimate_seen_mm", "estimate_hidden_mm")) for r in rows])


def zoo_report(results, rows):
    """registration_zoo.md, one row per shape and deformation, and its plot."""
    text = "# Registration over the zoo\n\n"
    text += ("`bench_registration_zoo`: five shapes (a sponge, a fruit, a banana, a thin plate, a "
             "toy figure; 8000 model points, linear, 6 clusters, the same defaults for all), each "
             "squeezed, bent, twisted, dented, and all at half amplitude while carried 4 cm and "
             "turned 15 degrees; 40 frames of motion, then 10 at rest; one 320 x 240 depth camera "
             "(1 mm noise, 5% dropout, 1% flying pixels). Errors in mm, mean over material points, "
             "seen / hidden side: the rest model left in place, ours at the end of the motion and "
             "after the rest, the share of the deformation recovered after the rest (1 - ours / "
             "rest model). Bounds after the rest: ours given the seen ground truth as its cloud, "
             "and each cluster's least-squares fit to the ground truth of its seen points with "
             "the correspondences known (what a perfect matching of the seen side leaves); the "
             "fit to all points is in registration_zoo_model_limit.csv.\n\n")
    text += table(["shape", "deformation", "rest model", "ours, end of motion", "ours, rested",
                   "recovered", "ours given the truth", "seen side fitted", "ms per cloud (worst)"],
                  [(r["shape"], r["deformation"], zoo_pair(r, "rest_seen_mm", "rest_hidden_mm"),
                    zoo_pair(r, "end_seen_mm", "end_hidden_mm"),
                    zoo_pair(r, "rested_seen_mm", "rested_hidden_mm"),
                    f"{100 * float(r['recovered_seen']):.0f}% / "
                    f"{100 * float(r['recovered_hidden']):.0f}%",
                    zoo_pair(r.get("truth"), "rested_seen_mm", "rested_hidden_mm"),
                    zoo_pair(r.get("seen_limit"), "rested_seen_mm", "rested_hidden_mm"),
                    f"{r['ms_per_cloud']} ({r['worst_ms']})") for r in rows])
    text += "\n" + zoo_targets(rows)
    text += "\n" + zoo_estimates(rows)
    write(results, "registration_zoo.md", text)
    zoo_plot(results, rows)


def zoo_plot(results, rows):
    """Error against frame, one panel per shape, one line per deformation (seen solid, hidden
    dashed); the motion ends at the dotted line."""
    path = os.path.join(results, "registration_zoo_frames.csv")
    if not os.path.exists(path):
        return
    with open(path) as f:
        frames = list(csv.DictReader(f))
    shapes = list(dict.fromkeys(r["shape"] for r in rows))
    fig, axes = plt.subplots(1, len(shapes), figsize=(4 * len(shapes), 4), sharey=True)
    for ax, shape in zip(axes, shapes):
        for i, deformation in enumerate(dict.fromkeys(r["deformation"] for r in rows)):
            series = [r for r in frames if r["shape"] == shape and r["deformation"] == deformation]
            x = [int(r["frame"]) for r in series]
            ax.plot(x, [float(r["seen_mm"]) for r in series], color=f"C{i}", label=f"{deformation}, seen")
            ax.plot(x, [float(r["hidden_mm"]) for r in series], "--", color=f"C{i}",
                    label=f"{deformation}, hidden")
        ax.axvline(39.5, linestyle=":", color="grey")
        ax.set_title(shape)
        ax.set_xlabel("frame")
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("mean error, mm")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="lower center", ncol=5, fontsize=7)
    fig.suptitle("Registration over the zoo: error against time")
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    fig.savefig(os.path.join(results, "registration_zoo_error_vs_time.png"), dpi=100)
    plt.close(fig)

ADD_OBJECT_SHAPES = {
    "thin_grid": "a grid of 2 layers",
    "thick_grid": "a grid of 16 layers",
    "random_box": "random points in a 16 cm thick box",
    "scanned_surface": "a noisy closed surface",
}
ADD_OBJECT_MAX_S = 3.0  # the target: every shape up to 1M points made within it
ADD_OBJECT_PER_POINT_SPREAD = 2.0  # and its time per point within this factor at all sizes


def read_registered_objects(results):
    """bench_registered_objects' rows, or None if it was not run."""
    path = os.path.join(results, "registered_objects.csv")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return list(csv.DictReader(f))


def registered_objects_report(results, rows):
    """registered_objects.md: the cycle's time against the registered objects, both ways."""
    text = "# Registered objects and the cycle\n\n"
    text += ("`bench_registered_objects`: N zoo objects (the five shapes in turn, each under the "
             "combined deformation, 0.5 m apart, 8000 points, 6 linear clusters) on a static "
             "floor, each registered to its own camera's cloud every frame for 50 frames, timed on "
             "one thread. *cycle*: the registrations in the cycle (Scene::registerCloud, then the "
             "cycle). *reader*: the node's way, the registrations on a copy (RegistrationFitter) "
             "in the reader's time, the cycle taking the fits over and gathering the points near "
             "each object for the next. Means per frame in ms.\n\n")
    by_way = {(int(r["objects"]), r["way"]): r for r in rows}
    counts = sorted({int(r["objects"]) for r in rows})
    text += table(["objects", "cycle, registering (of it: registrations)",
                   "cycle, taking over (of it: take-over)", "reader", "same states"],
                  [(n, f"{float(by_way[(n, 'cycle')]['cycle_ms_mean']):.3f} "
                       f"({float(by_way[(n, 'cycle')]['take_ms_mean']):.3f})",
                    f"{float(by_way[(n, 'reader')]['cycle_ms_mean']):.3f} "
                    f"({float(by_way[(n, 'reader')]['take_ms_mean']):.3f})",
                    f"{float(by_way[(n, 'reader')]['reader_ms_mean']):.3f}",
                    "yes" if by_way[(n, "reader")]["final_positions_equal"] == "1" else "no")
                   for n in counts if (n, "cycle") in by_way and (n, "reader") in by_way])
    write(results, "registered_objects.md", text)


THREADS_SCENES = {"pile": "S2 pile, finest level", "two_objects": "S1 two objects",
                  "three_objects": "S3 three objects"}


def read_threads(results):
    """bench_threads' rows by (scene, threads); none if the file is not there."""
    path = os.path.join(results, "threads.csv")
    if not os.path.exists(path):
        return {}
    return {(r["scene"], int(r["threads"])): r for r in read(results, "threads.csv")}


def threads_report(results, rows):
    text = "# The cycle on several threads\n\n"
    text += ("`bench/bench_threads.cpp`: each scene made with `SceneConfig::threads` 1, 2 and 4 "
             "and settled 150 cycles; then 30 blocks of 10 cycles, timed in turn on each count "
             "(the host's speed drifts over a run), and per stage the median of the blocks' "
             "means, in ms. Dynamic objects step on the pool once they hold 32k points; object "
             "pairs are queried on it once a detection has 32 candidate pairs; the response "
             "measures the normals between dynamic objects on it from 32 such pairs, resolves "
             "the pairs with a fixed object on it, object by object, from 32 of them, and moves "
             "and dents objects on it once 32 are dynamic (S2; S1 and S3 stay on one thread); it "
             "resolves the pairs between dynamic objects on the cycle's thread. The contacts and "
             "states are the same on every count (`test_scene_threads`).\n\n")
    text += table(["scene", "threads", "shape matching", "detection", "response", "whole cycle"],
                  [(THREADS_SCENES.get(scene, scene), threads,
                    f"{float(r['shape_matching_ms']):.3f}", f"{float(r['detection_ms']):.3f}",
                    f"{float(r['response_ms']):.3f}", f"{float(r['whole_ms']):.3f}")
                   for (scene, threads), r in rows.items()])
    write(results, "threads.md", text)


def threads_targets(rows):
    """The thread pool's targets, met or not; none if bench_threads did not run."""
    if not rows:
        return []

    def whole(scene, threads):
        return float(rows[(scene, threads)]["whole_ms"])

    two = whole("pile", 2) / whole("pile", 1)
    four = whole("pile", 4) / whole("pile", 2)
    small = max(whole(scene, 2) / whole(scene, 1) for scene in ("two_objects", "three_objects"))
    return [
        ("S2 finest level, whole cycle: threads 2 / threads 1 <= 0.6",
         f"{whole('pile', 2):.3f} / {whole('pile', 1):.3f} ms = {two:.2f}",
         "**met**" if two <= 0.6 else "**not met**"),
        ("S2 finest level, whole cycle: threads 4 <= 1.05 x threads 2 (2 cores)",
         f"{whole('pile', 4):.3f} / {whole('pile', 2):.3f} ms = {four:.2f}",
         "**met**" if four <= 1.05 else "**not met**"),
        ("S1 and S3: threads 2 not slower than threads 1 (within 5%)",
         f"worst threads 2 / threads 1 = {small:.2f}",
         "**met**" if small <= 1.05 else "**not met**"),
    ]


def read_self_collision(results):
    """bench_self_collision's rows by (clusters, points); none if the file is not there."""
    path = os.path.join(results, "self_collision.csv")
    if not os.path.exists(path):
        return {}
    return {(int(r["clusters"]), int(r["points"])): r for r in read(results, "self_collision.csv")}


def per_contact_us(row):
    return 1000.0 * float(row["self_query_ms"]) / max(1, int(row["self_contacts"]))


def flat_price(row):
    """What self_collision adds to the cycle of a strip that does not fold, as a share."""
    return float(row["flat_cycle_on_ms"]) / float(row["flat_cycle_off_ms"]) - 1.0


def self_collision_report(results, rows):
    text = "# S4: a strip folded onto itself (self_collision)\n\n"
    text += ("`bench/bench_self_collision.cpp`: a 40 x 10 cm strip of two layers, its contact "
             "distance its point spacing, bent into a U whose arms' inner faces are half a "
             "contact distance apart; the self-query to the leaves (least of 10), against PCL's "
             "kd-tree radius search with the same rest rule (least of 3). Self-contacts are leaf "
             "pairs; the kd-tree's are point pairs, every one under a leaf contact (missed: 0). "
             "Then the strip lying flat on a floor: the whole cycle with self_collision off and "
             "on (median of 21 blocks of 10 cycles, off and on in turn).\n\n")
    text += table(["clusters", "points", "self-query ms", "node pairs", "self-contacts",
                   "us per contact", "kd-tree ms", "kd-tree / ours", "flat cycle off / on ms"],
                  [(clusters, points, f"{float(r['self_query_ms']):.2f}", r["node_pairs"],
                    r["self_contacts"], f"{per_contact_us(r):.2f}", f"{float(r['kdtree_ms']):.1f}",
                    f"{float(r['kdtree_ms']) / float(r['self_query_ms']):.1f}",
                    f"{float(r['flat_cycle_off_ms']):.3f} / {float(r['flat_cycle_on_ms']):.3f}")
                   for (clusters, points), r in sorted(rows.items())])
    write(results, "self_collision.md", text)


def self_collision_targets(rows):
    """S4's targets per cluster count, met or not; none if bench_self_collision did not run."""
    targets = []
    for clusters in sorted({c for c, _ in rows}):
        sizes = sorted(p for c, p in rows if c == clusters)
        small, large = rows[(clusters, sizes[0])], rows[(clusters, sizes[-1])]
        spread = max(per_contact_us(rows[(clusters, p)]) for p in sizes) / \
            min(per_contact_us(rows[(clusters, p)]) for p in sizes)
        speedup = float(large["kdtree_ms"]) / float(large["self_query_ms"])
        price = max(flat_price(rows[(clusters, p)]) for p in sizes)
        targets += [
            (f"S4, {clusters} cluster(s): time per self-contact flat within 2x, "
             f"{int(small['points']) // 1000}k to {int(large['points']) // 1000}k",
             f"{spread:.2f}x", "**met**" if spread <= 2 else "**not met**"),
            (f"S4, {clusters} cluster(s): >= 10x faster than the kd-tree at "
             f"{int(large['points']) // 1000}k", f"{speedup:.1f}x",
             "**met**" if speedup >= 10 else "**not met**"),
            (f"S4, {clusters} cluster(s): self_collision on a strip that does not fold < 5% "
             "of the cycle", f"at most {100 * price:+.1f}%", "**met**" if price < 0.05 else "**not met**"),
        ]
    return targets


def distance_report(results):
    """distance.md: ~get_distance's query against FCL's distance(); False if not run."""
    path = os.path.join(results, "distance.csv")
    if not os.path.exists(path):
        return False
    with open(path) as f:
        rows = list(csv.DictReader(f))
    text = "# Distance beyond contact\n\n"
    text += ("`bench_distance`: S1's two quadratic balls held 2 cm apart and deforming, 20 steps; "
             "per step the closest points of the two clouds by our hierarchy to the leaves "
             "(exact), three levels above them (a lower bound and its error bound), and FCL's "
             "`distance()` on a `BVHModel<OBBRSS>` of each cloud refitted each step (a degenerate "
             "triangle per point: FCL's distance takes only triangle models). The run fails "
             "unless ours and FCL's distances agree within 1e-9 m. Means per query.\n\n")
    text += table(["points", "method", "ms per query", "of it refit", "distance m",
                   "error bound m", "node pairs"],
                  [(points_label(int(r["points"])), r["method"], f"{float(r['ms_per_query']):.4f}",
                    f"{float(r['refit_ms']):.4f}", f"{float(r['distance_m']):.6f}",
                    f"{float(r['error_bound_m']):.6f}", r["node_pairs"]) for r in rows])
    write(results, "distance.md", text)
    return True


def read_add_object(results):
    """The rows of bench_add_object, by (shape, kind) in the order they came; none if the
    file is not there."""
    path = os.path.join(results, "add_object.csv")
    if not os.path.exists(path):
        return {}
    series = {}
    for r in read(results, "add_object.csv"):
        series.setdefault((r["shape"], r["kind"]), []).append(r)
    for rows in series.values():
        rows.sort(key=lambda r: int(r["points"]))
    return series


def add_object_targets(series):
    """Per shape and kind: (slowest s, per-point spread, met) over its sizes."""
    verdicts = {}
    for key, rows in series.items():
        per_point = [float(r["us_per_point"]) for r in rows]
        slowest = max(float(r["add_ms"]) for r in rows) / 1000
        spread = max(per_point) / min(per_point)
        verdicts[key] = (slowest, spread,
                         slowest <= ADD_OBJECT_MAX_S and spread <= ADD_OBJECT_PER_POINT_SPREAD)
    return verdicts


def add_object_report(results, series):
    text = "# Making an object: Scene::addObject against its points\n\n"
    text += ("One object made in a new scene (`bench/bench_add_object.cpp`): clusters, rest "
             "moments, tree with exact rest spheres, then the first cycle. A static object's "
             "slabs and fixed planes are measured node by node when contacts first reach the "
             "node; the last column is all of them at once, the most its contacts can ever add. "
             "Points 1 cm apart (random points: one per cm³; the surface: one per cm², 1 mm of "
             "noise); contact distance 1 cm; dynamic objects linear, one cluster. One core; "
             "each row the least of 3 runs.\n\n")
    text += table(["shape", "kind", "points", "made in ms", "µs per point", "first cycle ms",
                   "every node's slab and plane ms"],
                  [(ADD_OBJECT_SHAPES.get(shape, shape), kind, r["points"],
                    f"{float(r['add_ms']):.1f}", f"{float(r['us_per_point']):.3f}",
                    f"{float(r['first_cycle_ms']):.2f}",
                    f"{float(r['every_node_ms']):.1f}" if r.get("every_node_ms") else "-")
                   for (shape, kind), rows in series.items() for r in rows])
    reset = read_reset_latency(results)
    if reset:
        text += ("\n## The node, a table rescanned with on_cloud: reset\n\n"
                 "`scripts/run_reset_latency`: a table top scanned at 10 Hz as an organized "
                 "cloud (`scripts/scan_publisher`, 1 mm of depth noise, new in every scan), "
                 "every scan the table's new rest shape (`bench/reset_latency.yaml`), a soft "
                 "ball resting on it, the nodelet cycling at 100 Hz. Latency: a scan's stamp "
                 "to the publication of its first cycle's contacts (the node's ~stats), after "
                 "a warm-up of 3 s; the reader thread makes each new table.\n\n")
        text += table(["points", "scans published", "received", "coalesced", "rejected",
                       "latency mean ms", "worst 1 s p99 ms", "max ms", "reader busy"],
                      [(r["points"], r["scans_published"], scans_received(r),
                        r["clouds_coalesced"],
                        r["clouds_rejected"], r["stamp_mean_ms"], r["stamp_p99_ms"],
                        r["stamp_max_ms"], f"{r['reader_busy_percent']}%") for r in reset])
    write(results, "add_object.md", text)

    fig, axes = plt.subplots(1, 2, figsize=(13, 5), squeeze=False)
    for ax, kind in zip(axes[0], ("static", "dynamic")):
        for (shape, k), rows in series.items():
            if k == kind:
                ax.loglog([int(r["points"]) for r in rows], [float(r["add_ms"]) for r in rows],
                          marker="o", label=ADD_OBJECT_SHAPES.get(shape, shape))
        ax.axhline(ADD_OBJECT_MAX_S * 1000, color="grey", linestyle="--", linewidth=1,
                   label=f"target {ADD_OBJECT_MAX_S:g} s")
        ax.set_xlabel("points in the object")
        ax.set_ylabel("Scene::addObject, ms")
        ax.set_title(f"Making a {kind} object")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(results, "add_object_time_vs_points.png"), dpi=110)
    plt.close(fig)


def points_label(points):
    """300304 -> 300k, 999698 -> 1M: the sizes asked for, not the grids' exact counts."""
    return f"{round(points / 1e5) / 10:g}M" if points >= 950000 else f"{round(points / 1e4) * 10}k"


RESET_LATENCY_POINTS = 100000  # the target: a 100k-point scan reset at 10 Hz ...
RESET_LATENCY_MAX_MS = 100.0  # ... every scan's contacts published within this


def read_reset_latency(results):
    path = os.path.join(results, "reset_latency.csv")
    return read(results, "reset_latency.csv") if os.path.exists(path) else []


def scans_received(row):
    """The node's count of clouds less the ball's one."""
    return int(row["clouds_received"]) - 1


def reset_latency_target(results):
    row = next((r for r in read_reset_latency(results)
                if int(r["points"]) == RESET_LATENCY_POINTS), None)
    what = (f"on_cloud: reset, {RESET_LATENCY_POINTS // 1000}k-point scans at 10 Hz: every "
            f"scan's contacts published, latency <= {RESET_LATENCY_MAX_MS:g} ms")
    if row is None:
        return [(what, "not run", "**not met**")]
    every = (int(row["clouds_coalesced"]) == 0 and int(row["clouds_rejected"]) == 0 and
             scans_received(row) == int(row["scans_published"]))
    worst = float(row["stamp_max_ms"])
    return [(what, f"{scans_received(row)} of {row['scans_published']} scans received, "
             f"{row['clouds_coalesced']} coalesced, "
             f"mean {row['stamp_mean_ms']} ms, worst p99 {row['stamp_p99_ms']} ms, "
             f"max {row['stamp_max_ms']} ms",
             "**met**" if every and worst <= RESET_LATENCY_MAX_MS else "**not met**")]


def add_object_target_rows(series):
    rows = []
    for (shape, kind), (slowest, spread, met) in add_object_targets(series).items():
        sizes = [int(r["points"]) for r in series[(shape, kind)]]
        rows.append((f"Making {ADD_OBJECT_SHAPES.get(shape, shape)} ({kind}), "
                     f"{points_label(sizes[0])} to {points_label(sizes[-1])} points: "
                     f"<= {ADD_OBJECT_MAX_S:g} s, time per point within "
                     f"{ADD_OBJECT_PER_POINT_SPREAD:g}x",
                     f"slowest {slowest:.2f} s, time per point spread {spread:.2f}x",
                     "**met**" if met else "**not met**"))
    return rows


def add_object_headline(series):
    """The slowest of the largest objects of every shape and kind."""
    ms, shape, kind, points = max((float(rows[-1]["add_ms"]), shape, kind, int(rows[-1]["points"]))
                                  for (shape, kind), rows in series.items())
    return (f"Making an object of {points_label(points)} points: the slowest shape",
            f"{ms / 1000:.2f} s ({ADD_OBJECT_SHAPES.get(shape, shape)}, {kind})")


def peer_target(ms, methods, distance, points, factor):
    """The target row: ours at least `factor` times faster than the best peer."""
    if (distance, points, OURS) not in ms:
        return (f"S1 {s1_case_name(distance)} at {points // 1000}k points: >= {factor}x faster "
                "than the best peer", "not run", "**not met**")
    ours = ms[(distance, points, OURS)]
    peer = best_peer(ms, distance, points, methods)
    measured = ms[(distance, points, peer)] / ours
    return (f"S1 {s1_case_name(distance)} at {points // 1000}k points: >= {factor}x faster than "
            "the best peer",
            f"{OURS} {ours:.3f} ms, best peer {peer} {ms[(distance, points, peer)]:.3f} ms: "
            f"{measured:.1f}x", "**met**" if measured >= factor else "**not met**")


def auto_target(auto):
    """The target row of S2's `level: auto` run."""
    within = float(auto["within_budget_share"])
    most = auto_most_run_level(auto)
    return ("S2 level: auto, budget half the finest level's detection + response: within it in "
            ">= 95% of cycles, at a level above 1",
            f"budget {float(auto['budget_ms']):.2f} ms: {100 * within:.1f}% of {auto['cycles']} "
            f"cycles within ({100 * float(auto['within_budget_share_after_climb']):.1f}% after the "
            f"first {auto['climb_cycles']}), levels {auto['level_min']} / {float(auto['level_mean']):.2f} / "
            f"{auto['level_max']} (min / mean / max), most run {most}",
            "**met**" if within >= 0.95 and most > 1 else "**not met**")


def targets_table(results, sizes, ms, methods, s2_rows, s3, forces, add_object):
    """The issue's targets, met or not."""
    largest, smallest = sizes[-1], sizes[0]
    near = {(p, m): v for (d, p, m), v in ms.items() if d == NEAR_MISS_M}
    ours = near[(largest, OURS)]
    refit_factor = near[(largest, "full_refit")] / ours
    growth = ours / near[(smallest, OURS)]
    finest = s2_rows[-1]
    finest_total = float(finest["total_ms"])
    s3_cycle = s3["whole_cycle"]

    def verdict(ok):
        return "**met**" if ok else "**not met**"

    return table(["target", "measured", "verdict"], [
        peer_target(ms, methods, NEAR_MISS_M, largest, 10),
        peer_target(ms, methods, NEAR_MISS_M, largest, 50),
        peer_target(ms, methods, DENSE_M, largest, 10),
        (f"S1 near miss at {largest // 1000}k points: >= 10x faster than the full refit",
         f"full_refit {near[(largest, 'full_refit')]:.3f} ms: {refit_factor:.1f}x", verdict(refit_factor >= 10)),
        (f"S1 near miss: time at {largest // 1000}k / time at {smallest // 1000}k <= 3",
         f"{ours:.3f} / {near[(smallest, OURS)]:.3f} ms = {growth:.1f} "
         f"(full_refit {near[(largest, 'full_refit')] / near[(smallest, 'full_refit')]:.1f})",
         verdict(growth <= 3)),
        (f"S2 finest level ({finest['level']}): detection + response <= 10 ms",
         f"{float(finest['detection_ms']):.2f} + {float(finest['response_ms']):.2f} = {finest_total:.2f} ms",
         verdict(finest_total <= 10)),
        *s2_level_targets(s2_rows, read(results, "s2_rest.csv")),
        auto_target(read(results, "s2_auto.csv")[0]),
        ("S3: whole cycle <= 1 ms", f"{s3_cycle:.3f} ms (with the PointCloud2 conversion)",
         verdict(s3_cycle <= 1)),
        *forces_targets(forces),
        *add_object_target_rows(add_object),
        *(reset_latency_target(results) if add_object else []),
        *threads_targets(read_threads(results)),
        *self_collision_targets(read_self_collision(results)),
    ])


def s1_headline(ms, methods, distance, points):
    """Ours against the best peer in S1."""
    ours = ms[(distance, points, OURS)]
    other = best_peer(ms, distance, points, methods)
    return (f"S1 {s1_case_name(distance)}, {points // 1000}k points: ours against the best peer",
            f"{ours:.3f} ms against {other} {ms[(distance, points, other)]:.3f} ms: "
            f"{ms[(distance, points, other)] / ours:.1f}x faster")


def headline_table(sizes, ms, methods, s2_rows, s3, registration, add_object):
    """The few figures README shows; the targets table holds the rest."""
    largest = sizes[-1]
    finest = s2_rows[-1]
    finest_total = float(finest["total_ms"])
    rows = [s1_headline(ms, methods, NEAR_MISS_M, largest),
            (f"S2 pile, finest level ({finest['level']}): detection + response",
             f"{float(finest['detection_ms']):.2f} + {float(finest['response_ms']):.2f} = "
             f"{finest_total:.2f} ms")]
    rows.append(("S3 whole cycle, with the PointCloud2 conversion", f"{s3['whole_cycle']:.3f} ms"))
    ours = registration_defaults(registration)
    rest = next((r for r in registration if r["kind"] == "rest"), None)
    if ours:
        rows.append((f"Sponge registration ({ours['iterations']} x {ours['cloud_points']} "
                     "points): mean error seen / hidden",
                     f"{ours['seen']} / {ours['hidden']} mm at {ours['ms']} ms per cloud" +
                     (f" (rest model left in place: {rest['seen']} / {rest['hidden']} mm)" if rest else "")))
    if add_object:
        rows.append(add_object_headline(add_object))
    return table(["figure", "this run"], rows)


def summary(results, headline, targets):
    """summary.md: the headline figures, then the targets."""
    write(results, "summary.md",
          "# Summary\n\n## Headline\n\n" + headline + "\n## Targets\n\n" + targets)


PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
INTRO = os.path.join(PACKAGE, "bench", "benchmarks_intro.md")
DOC = os.path.join(PACKAGE, "docs", "benchmarks.md")
README = os.path.join(PACKAGE, "README.md")
README_BLOCK = re.compile(r"^<!-- results:begin \(written by bench/report\.py\) -->\n(.*?)"
                          r"^<!-- results:end -->$", re.S | re.M)


def demoted(text):
    """The markdown one heading level down, to sit under the page's title; code blocks kept."""
    lines, in_code = [], False
    for line in text.splitlines():
        in_code ^= line.startswith("```")
        lines.append("#" + line if line.startswith("#") and not in_code else line)
    return "\n".join(lines) + "\n"


def doc_section(results, name, note="", plot=None):
    """One markdown file of the results under its own heading, with a link to it, a note
    and its plot."""
    with open(os.path.join(results, name)) as f:
        heading, body = demoted(f.read()).split("\n", 1)
    text = f"{heading} ([{name}](../bench/results/{name}))\n\n" + (note + "\n\n" if note else "")
    text += body.lstrip("\n")
    if plot:
        text += f"\n![{plot}](../bench/results/{plot})\n"
    return text


def benchmarks_doc(results, registration, forces, add_object, zoo, registered_objects, distance):
    """docs/benchmarks.md: the fixed introduction, then every table and plot of this run."""
    sections = [doc_section(results, "summary.md"),
                doc_section(results, "s1.md", plot="s1_time_vs_points.png"),
                doc_section(results, "s2.md", plot="s2_error_vs_time.png"),
                doc_section(results, "s3.md")]
    if forces:
        sections.append(doc_section(results, "forces.md"))
    if registration:
        sections.append(doc_section(results, "registration.md",
                                    plot="registration_error_vs_time.png"))
    if zoo:
        sections.append(doc_section(results, "registration_zoo.md",
                                    plot="registration_zoo_error_vs_time.png"))
    if registered_objects:
        sections.append(doc_section(results, "registered_objects.md"))
    if add_object:
        sections.append(doc_section(results, "add_object.md", plot="add_object_time_vs_points.png"))
    if distance:
        sections.append(doc_section(results, "distance.md"))
    if os.path.exists(os.path.join(results, "threads.md")):
        sections.append(doc_section(results, "threads.md"))
    if os.path.exists(os.path.join(results, "self_collision.md")):
        sections.append(doc_section(results, "self_collision.md"))
    sections.append(doc_section(results, "memory.md"))
    if os.path.exists(os.path.join(results, "latency.md")):
        sections.append(doc_section(results, "latency.md", note=(
            "Written by `make latency` (`scripts/run_latency`), not by `make bench`: from its own "
            "run, at another time than the tables above.")))
    with open(INTRO) as f:
        intro = f.read()
    with open(DOC, "w") as f:
        f.write("<!-- Generated by bench/report.py from bench/results/ (make bench): do not edit "
                "by hand. -->\n" + intro + "\n" + "\n".join(sections))


def readme_block(headline):
    """Puts the headline table between README's results markers; False, and README left
    alone, without them."""
    with open(README) as f:
        text = f.read()
    match = README_BLOCK.search(text)
    if not match:
        return False
    block = (headline + "\nFull report: `bench/results/summary.md` and "
             "[docs/benchmarks.md](docs/benchmarks.md), written by `make bench`.\n")
    new = text[:match.start(1)] + block + text[match.end(1):]
    if new != text:
        with open(README, "w") as f:
            f.write(new)
    return True


def main():
    results = sys.argv[1] if len(sys.argv) > 1 else "bench/results"
    sizes, ms, methods = s1_report(results)
    s2_rows = s2_report(results)
    s3 = s3_report(results)
    forces = forces_report(results)
    memory_report(results)
    registration = read_registration(results)
    if registration:
        registration_report(results, registration)
    zoo = read_zoo(results)
    if zoo:
        zoo_report(results, zoo)
    registered_objects = read_registered_objects(results)
    if registered_objects:
        registered_objects_report(results, registered_objects)
    add_object = read_add_object(results)
    if add_object:
        add_object_report(results, add_object)
    distance = distance_report(results)
    threads = read_threads(results)
    if threads:
        threads_report(results, threads)
    self_collision = read_self_collision(results)
    if self_collision:
        self_collision_report(results, self_collision)
    headline = headline_table(sizes, ms, methods, s2_rows, s3, registration, add_object)
    summary(results, headline,
            targets_table(results, sizes, ms, methods, s2_rows, s3, forces, add_object))
    for name in ["summary.md", "s1.md", "s2.md", "s3.md", "memory.md"] + \
            (["forces.md"] if forces else []) + \
            (["registration.md"] if registration else []) + \
            (["registration_zoo.md"] if zoo else []) + \
            (["registered_objects.md"] if registered_objects else []) + \
            (["add_object.md"] if add_object else []) + \
            (["distance.md"] if distance else []) + \
            (["threads.md"] if threads else []) + \
            (["self_collision.md"] if self_collision else []):
        with open(os.path.join(results, name)) as f:
            print(f.read())
    print(f"report: {results}/ (markdown, CSV, s1_time_vs_points.png, s2_error_vs_time.png, "
          "registration_error_vs_time.png, registration_zoo_error_vs_time.png, "
          "add_object_time_vs_points.png)")
    # The page and README link to bench/results/: a run on another directory leaves them alone.
    if os.path.realpath(results) != os.path.realpath(os.path.join(PACKAGE, "bench", "results")):
        print(f"report: {results} is not bench/results; docs/benchmarks.md and README.md left alone")
        return
    benchmarks_doc(results, registration, forces, add_object, zoo, registered_objects, distance)
    print("report: docs/benchmarks.md written")
    if not readme_block(headline):
        print("report: README.md has no results markers; left alone")


if __name__ == "__main__":
    main()
