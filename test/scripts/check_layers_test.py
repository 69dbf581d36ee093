"""Tests of scripts/check_layers.py: the repository keeps its layers, and a tie that runs back
up is caught."""
import importlib.util
import os
import shutil
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_spec = importlib.util.spec_from_file_location(
    "check_layers", os.path.join(ROOT, "scripts", "check_layers.py"))
check_layers = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(check_layers)


class CheckLayersTest(unittest.TestCase):
    def test_the_repository_has_no_tie_that_runs_back_up(self):
        found, unknown = check_layers.violations(ROOT)
        self.assertEqual(found, [])
        self.assertEqual(unknown, [])

    def test_the_table_is_acyclic(self):
        state = {}

        def visit(folder, path):
            self.assertNotEqual(state.get(folder), "open", " -> ".join(path + [folder]))
            if state.get(folder) == "done":
                return
            state[folder] = "open"
            for dep in check_layers.ALLOWED[folder]:
                visit(dep, path + [folder])
            state[folder] = "done"

        for folder in check_layers.ALLOWED:
            visit(folder, [])

    def _tree(self, files):
        root = tempfile.mkdtemp()
        self.addCleanup(shutil.rmtree, root)
        for rel, text in files.items():
            path = os.path.join(root, rel)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w") as f:
                f.write(text)
        return root

    def test_an_include_that_runs_back_up_is_reported_with_its_line(self):
        root = self._tree({
            "src/localization/localizer.cpp":
                '#include <vector>\n#include "osm_graph_slam/slam/graph_backend.h"\n',
            "src/slam/graph_backend.cpp": '#include "osm_graph_slam/localization/localizer.h"\n',
        })
        found, unknown = check_layers.violations(root)
        self.assertEqual(found, [("src/localization/localizer.cpp", 2, "slam")])
        self.assertEqual(unknown, [])
        self.assertEqual(check_layers.main(["check_layers.py", root]), 1)

    def test_a_folder_outside_the_table_is_reported(self):
        root = self._tree({"src/newstage/a.cpp": '#include "osm_graph_slam/common/logger.h"\n'})
        found, unknown = check_layers.violations(root)
        self.assertEqual(found, [])
        self.assertEqual(unknown, ["newstage"])


if __name__ == "__main__":
    unittest.main()
