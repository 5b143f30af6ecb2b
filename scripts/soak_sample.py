#!/usr/bin/env python3
"""The sampler and the report of scripts/soak.sh (system python3, no numpy).

  soak_sample.py sample --out CSV --seconds S --interval I --nodes /a,/b [--topics /t1,/t2]
      a rospy node: every I seconds for S seconds one CSV row: t_s (from the
      start), per node its PID (the node's getPid, the master's for /master;
      the last one while the node does not answer but its process is there)
      and VmRSS in kB (both empty once the node is gone), per topic its
      message rate in Hz over the interval (rospy.AnyMsg: counted, never
      deserialised).
  soak_sample.py report CSV --warmup S --max-growth-mb X --max-rate-drop F
      the table; exits 1 with one line per failure: a node whose RSS grew by
      more than X MB after the warm-up (median of the last 3 samples minus the
      median of the first 3 after it), a node that died or changed PID, a
      topic whose mean rate over the last 20 % of the samples after the
      warm-up (but at least 60 s, at most half) is more than F below that over
      the first 20 % (or that is silent).
"""
import argparse
import csv
import math
import statistics
import sys
import threading
import time
import xmlrpc.client

DEFAULT_TOPICS = ['/stereo/left/image_raw', '/stereo/disparity', '/stereo/acupoints', '/tf', '/joint_states']


class _Transport(xmlrpc.client.Transport):
    """An XML-RPC transport with a timeout, so a hung node does not hang the sampler."""

    def make_connection(self, host):
        conn = super().make_connection(host)
        conn.timeout = 3.0
        return conn


def node_pid(master, name):
    try:
        if name == '/master':
            return master.getPid()
        code, _, pid = xmlrpc.client.ServerProxy(master.lookupNode(name), transport=_Transport()).getPid(
            master.caller_id)
        return pid if code == 1 else None
    except Exception:  # not registered, or registered but its process is gone
        return None


def rss_kb(pid):
    try:
        with open('/proc/%d/status' % pid) as f:
            for line in f:
                if line.startswith('VmRSS:'):
                    return int(line.split()[1])
    except OSError:
        pass
    return None  # gone, or a zombie (no VmRSS)


def sample(args):
    import rosgraph
    import rospy
    rospy.init_node('soak_sampler', anonymous=True)
    master = rosgraph.Master(rospy.get_name())
    nodes, topics = args.nodes.split(','), args.topics.split(',')
    counts = dict.fromkeys(topics, 0)
    lock = threading.Lock()

    def count(_, topic):
        with lock:
            counts[topic] += 1

    # Large buffers: an image or a disparity map is ~1 MB.
    subs = [rospy.Subscriber(t, rospy.AnyMsg, count, callback_args=t, queue_size=10, buff_size=1 << 24)
            for t in topics]
    with open(args.out, 'w', newline='') as f:
        out = csv.writer(f)
        out.writerow(['t_s'] + ['pid:' + n for n in nodes] + ['rss_kB:' + n for n in nodes] +
                     ['hz:' + t for t in topics])
        f.flush()
        start = last = time.monotonic()
        last_pid = {}
        k = 1
        while not rospy.is_shutdown():
            time.sleep(max(0.0, start + k * args.interval - time.monotonic()))
            now = time.monotonic()
            with lock:
                window = dict(counts)
                for t in topics:
                    counts[t] = 0
            # A node that does not answer (busy, stopped) but whose process is still there keeps its PID.
            pids = [node_pid(master, n) or (last_pid.get(n) if rss_kb(last_pid.get(n, 0)) else None) for n in nodes]
            last_pid.update((n, p) for n, p in zip(nodes, pids) if p)
            rss = [rss_kb(p) if p else None for p in pids]
            out.writerow(['%.1f' % (now - start)] + ['' if p is None else p for p in pids] +
                         ['' if r is None else r for r in rss] +
                         ['%.2f' % (window[t] / (now - last)) for t in topics])
            f.flush()
            last = now
            if now - start >= args.seconds - 0.5:
                break
            k += 1
    for s in subs:
        s.unregister()


def report(args):
    with open(args.csv) as f:
        rows = list(csv.DictReader(f))
    if not rows:
        print('soak: no samples in %s' % args.csv)
        return 1
    nodes = [c[4:] for c in rows[0] if c.startswith('pid:')]
    topics = [c[3:] for c in rows[0] if c.startswith('hz:')]
    post = [r for r in rows if float(r['t_s']) >= args.warmup]
    failures = []
    if len(post) < 6:
        failures.append('only %d samples after the warm-up (need 6): soak longer or sample more often' % len(post))
        post = rows

    print('\n%-26s %8s %12s %10s %10s %8s' % ('node', 'pid', 'warm-up MB', 'end MB', 'growth MB', 'max MB'))
    for n in nodes:
        pids = [r['pid:' + n] for r in rows]
        rss = [int(r['rss_kB:' + n]) / 1024.0 for r in post if r['rss_kB:' + n]]
        peak = max((int(r['rss_kB:' + n]) / 1024.0 for r in rows if r['rss_kB:' + n]), default=float('nan'))
        died = next((r for r in rows if r['pid:' + n] != pids[0] or not r['rss_kB:' + n]), None)
        if died is not None:
            print('%-26s %8s %12s %10s %10s %8.1f' % (n, pids[0] or '-', '-', '-', '-', peak))
            failures.append('node %s died: PID %s at the start, %s at t=%s s' % (
                n, pids[0] or 'none', died['pid:' + n] or 'gone', died['t_s']))
            continue
        base, end = statistics.median(rss[:3]), statistics.median(rss[-3:])
        print('%-26s %8s %12.1f %10.1f %+10.2f %8.1f' % (n, pids[0], base, end, end - base, peak))
        if end - base > args.max_growth_mb:
            curve = ' '.join('%.1f' % x for x in rss[::max(1, len(rss) // 10)])
            failures.append('node %s: RSS grew %.2f MB after the warm-up (limit %.2f MB; MB over time: %s)' % (
                n, end - base, args.max_growth_mb, curve))

    # At least 60 s per window (the massage session's ~75 s cycle modulates the load, HBDS's rate
    # with it), at most half of the samples each.
    dt = statistics.median(float(b['t_s']) - float(a['t_s']) for a, b in zip(post, post[1:])) if len(post) > 1 else 1
    k = max(1, min(max(round(0.2 * len(post)), math.ceil(60 / dt)), len(post) // 2))
    print('\n%-26s %12s %12s %8s   (mean of the first / last %d samples after the warm-up)' % (
        'topic', 'first Hz', 'last Hz', 'drop %', k))
    for t in topics:
        hz = [float(r['hz:' + t]) for r in post]
        first, last = statistics.mean(hz[:k]), statistics.mean(hz[-k:])
        drop = (first - last) / first if first > 0 else float('nan')
        print('%-26s %12.2f %12.2f %8.1f' % (t, first, last, 100 * drop))
        if first <= 0:
            failures.append('topic %s: no messages after the warm-up' % t)
        elif drop > args.max_rate_drop:
            failures.append('topic %s: rate dropped %.0f %% (%.2f -> %.2f Hz; limit %.0f %%)' % (
                t, 100 * drop, first, last, 100 * args.max_rate_drop))
    print()
    for f in failures:
        print('soak: FAIL: ' + f)
    return 1 if failures else 0


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest='cmd', required=True)
    s = sub.add_parser('sample')
    s.add_argument('--out', required=True)
    s.add_argument('--seconds', type=float, required=True)
    s.add_argument('--interval', type=float, default=10.0)
    s.add_argument('--nodes', required=True, help='comma-separated node names; /master for the ROS master')
    s.add_argument('--topics', default=','.join(DEFAULT_TOPICS))
    r = sub.add_parser('report')
    r.add_argument('csv')
    r.add_argument('--warmup', type=float, default=180.0, help='s')
    r.add_argument('--max-growth-mb', type=float, default=1.0)
    r.add_argument('--max-rate-drop', type=float, default=0.2)
    args, _ = p.parse_known_args()  # rospy remappings (__name:=...) may follow
    if args.cmd == 'sample':
        sample(args)
        return 0
    return report(args)


if __name__ == '__main__':
    sys.exit(main())
