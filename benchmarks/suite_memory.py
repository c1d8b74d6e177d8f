"""Which tests raise a pytest worker's memory peak: a summary of a ``BRDFFIT_TEST_MEMLOG`` file.

Usage::

    BRDFFIT_TEST_MEMLOG=/tmp/mem.log pytest -q -p no:cacheprovider
    python benchmarks/suite_memory.py /tmp/mem.log [--top 15]

``tests/conftest.py`` appends ``pid VmRSS VmHWM nodeid`` (KiB) after every test. This prints each
worker's peak (VmHWM, the high-water mark of its resident memory) against the 3 GB goal per test
process, the tests during which a worker's high-water mark rose the most, and the test files whose
tests end with the most resident memory.
"""

from __future__ import annotations

import argparse
from collections import defaultdict

GOAL_GB = 3.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("--top", type=int, default=15)
    args = ap.parse_args(argv)
    rows = []
    with open(args.log) as fh:
        for line in fh:
            pid, rss, hwm, nodeid = line.rstrip("\n").split(" ", 3)
            rows.append((int(pid), int(rss), int(hwm), nodeid))
    last_hwm: dict[int, int] = {}
    rises = []
    by_file: dict[str, int] = defaultdict(int)
    for pid, rss, hwm, nodeid in rows:
        rises.append((hwm - last_hwm.get(pid, 0), hwm, pid, nodeid))
        last_hwm[pid] = hwm
        f = nodeid.split("::")[0]
        by_file[f] = max(by_file[f], rss)
    print(f"{len(rows)} tests, {len(last_hwm)} worker processes")
    for pid, hwm in sorted(last_hwm.items()):
        print(f"  worker {pid}: peak {hwm / 2**20:.2f} GB "
              f"(goal {GOAL_GB:.1f} GB: ratio {hwm / 2**20 / GOAL_GB:.2f})")
    print(f"\nthe {args.top} largest rises of a worker's peak (GB rise, peak after, test):")
    for rise, hwm, pid, nodeid in sorted(rises, reverse=True)[: args.top]:
        print(f"  +{rise / 2**20:5.2f}  {hwm / 2**20:5.2f}  {nodeid}")
    print(f"\nthe {args.top} test files with the most resident memory after one of their tests:")
    for f, rss in sorted(by_file.items(), key=lambda kv: -kv[1])[: args.top]:
        print(f"  {rss / 2**20:5.2f} GB  {f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
