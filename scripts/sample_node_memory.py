"""Samples the resident memory of a ROS node's process every 5 s for a duration and prints
its growth after a warm-up. The pid comes from the node's own XML-RPC API (getPid).

usage: sample_node_memory.py NODE DURATION_S WARMUP_S CSV
"""
import os
import sys
import time
import xmlrpc.client

CALLER = "/sample_node_memory"
PERIOD_S = 5.0


def node_pid(node, timeout_s=60.0):
    master = xmlrpc.client.ServerProxy(os.environ["ROS_MASTER_URI"])
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            code, _, uri = master.lookupNode(CALLER, node)
            if code == 1:
                code, _, pid = xmlrpc.client.ServerProxy(uri).getPid(CALLER)
                if code == 1:
                    return pid
        except (OSError, xmlrpc.client.Error):
            pass
        time.sleep(0.5)
    raise SystemExit("sample_node_memory: no pid for %s within %.0f s" % (node, timeout_s))


def resident_kib(pid):
    with open("/proc/%d/status" % pid) as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise ValueError("no VmRSS")


def main():
    node, duration_s, warmup_s, csv_path = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
    pid = node_pid(node)
    start = time.monotonic()
    samples = []
    with open(csv_path, "w") as csv:
        csv.write("time_s,rss_mib\n")
        while time.monotonic() - start < duration_s:
            try:
                rss_mib = resident_kib(pid) / 1024.0
            except (OSError, ValueError):
                print("sample_node_memory: %s (pid %d) is gone after %.0f s" % (node, pid, time.monotonic() - start))
                return 1
            t = time.monotonic() - start
            samples.append((t, rss_mib))
            csv.write("%.1f,%.1f\n" % (t, rss_mib))
            csv.flush()
            time.sleep(PERIOD_S)
    after_warmup = [s for s in samples if s[0] >= warmup_s]
    if len(after_warmup) < 2:
        print("sample_node_memory: too short for a warm-up of %.0f s" % warmup_s)
        return 1
    (t0, rss0), (t1, rss1) = after_warmup[0], after_warmup[-1]
    peak = max(s[1] for s in samples)
    print("resident memory of %s: %.1f MiB at %.0f s (after warm-up), %.1f MiB at %.0f s, "
          "growth %+.1f MiB (%+.2f%%), peak %.1f MiB; samples in %s"
          % (node, rss0, t0, rss1, t1, rss1 - rss0, 100.0 * (rss1 - rss0) / rss0, peak, csv_path))
    return 0


if __name__ == "__main__":
    sys.exit(main())
