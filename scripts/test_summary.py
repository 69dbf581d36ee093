#!/usr/bin/env python3
"""Summarise the JUnit XML files written by catkin run_tests (gtest and rostest).

Prints failing test cases, then one line "N passed, N failed, N skipped" and exits non-zero when
anything failed, a test program crashed before writing results, or the build failed.
"""
import argparse
import glob
import os
import sys
import xml.etree.ElementTree as ET


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("results_dir")
    ap.add_argument("--build-status", type=int, default=0)
    args = ap.parse_args()

    passed = failed = skipped = 0
    failures = []
    files = sorted(glob.glob(os.path.join(args.results_dir, "**", "*.xml"), recursive=True))
    for path in files:
        name = os.path.relpath(path, args.results_dir)
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as exc:
            failed += 1
            failures.append(f"{name}: unreadable result file ({exc})")
            continue
        cases = list(root.iter("testcase"))
        if not cases:
            # catkin writes a <testsuite> with a failure when a test program crashed or is missing.
            if root.find(".//failure") is not None or root.find(".//error") is not None:
                failed += 1
                failures.append(f"{name}: test program failed without test cases")
            continue
        for case in cases:
            label = f"{case.get('classname', '')}.{case.get('name', '')}"
            if case.find("failure") is not None or case.find("error") is not None:
                failed += 1
                node = case.find("failure") if case.find("failure") is not None else case.find("error")
                msg = (node.get("message") or node.text or "").strip().splitlines()
                failures.append(f"{label}: {msg[0] if msg else ''}")
            elif case.find("skipped") is not None or case.get("status") == "notrun":
                skipped += 1
            else:
                passed += 1

    for f in failures:
        print(f"FAILED {f}")
    if args.build_status != 0:
        print(f"build or test run exited with status {args.build_status} (see build_ws/test.log)")
        failed += 0 if failures else 1
    if not files:
        print("no test result files found")
    print(f"{passed} passed, {failed} failed, {skipped} skipped")
    return 1 if failed or args.build_status != 0 or not files else 0


if __name__ == "__main__":
    sys.exit(main())
