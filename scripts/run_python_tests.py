#!/usr/bin/python3
"""Runs the Python unit tests (test/scripts/*_test.py) and writes a JUnit XML file that
scripts/test_summary.py counts with the gtests and rostests.

  run_python_tests.py OUT.xml
"""
import os
import sys
import time
import unittest
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class _Recorder(unittest.TextTestResult):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.cases = []  # (test, outcome, message, seconds)
        self._t0 = 0.0

    def startTest(self, test):
        self._t0 = time.monotonic()
        super().startTest(test)

    def _record(self, test, outcome, message=""):
        self.cases.append((test, outcome, message, time.monotonic() - self._t0))

    def addSuccess(self, test):
        super().addSuccess(test)
        self._record(test, "ok")

    def addFailure(self, test, err):
        super().addFailure(test, err)
        self._record(test, "failure", self._exc_info_to_string(err, test))

    def addError(self, test, err):
        super().addError(test, err)
        self._record(test, "error", self._exc_info_to_string(err, test))

    def addSkip(self, test, reason):
        super().addSkip(test, reason)
        self._record(test, "skipped", reason)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    suite = unittest.defaultTestLoader.discover(os.path.join(ROOT, "test", "scripts"),
                                                pattern="*_test.py",
                                                top_level_dir=os.path.join(ROOT, "test", "scripts"))
    runner = unittest.TextTestRunner(resultclass=_Recorder, verbosity=1)
    result = runner.run(suite)
    root = ET.Element("testsuite", name="python", tests=str(len(result.cases)))
    for test, outcome, message, seconds in result.cases:
        case = ET.SubElement(root, "testcase", classname=type(test).__name__,
                             name=test._testMethodName, time="%.3f" % seconds)
        if outcome in ("failure", "error"):
            ET.SubElement(case, outcome, message=message.strip().splitlines()[-1]).text = message
        elif outcome == "skipped":
            ET.SubElement(case, "skipped", message=message)
    os.makedirs(os.path.dirname(os.path.abspath(sys.argv[1])), exist_ok=True)
    ET.ElementTree(root).write(sys.argv[1], encoding="utf-8", xml_declaration=True)
    return 0 if result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main())
