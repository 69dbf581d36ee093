"""Every command-line tool (src/tools/*.cpp) answers --help and refuses bad command lines.

For each tool built in build_ws/devel/lib/osm_graph_slam (or $OGS_TOOLS_BIN):
  - `TOOL --help` and `TOOL -h` exit 0 with the usage on stdout, naming every option and
    positional argument the tool's source declares (src/tools/support/command_line.h);
  - an unknown option exits 2 naming it, on stderr;
  - a value option without its value exits 2 saying so.
Skipped when the tools are not built.

    /usr/bin/python3 -m unittest discover -s test/scripts -p '*_test.py'     (from the repo root)
"""
import glob
import os
import re
import subprocess
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
TOOLS_DIR = os.path.join(REPO, "src", "tools")
BIN = os.environ.get("OGS_TOOLS_BIN",
                     os.path.join(REPO, "build_ws", "devel", "lib", "osm_graph_slam"))

# A declaration: .option("--name", ...), .flag("--name", ...), .alias("-x"), .positional("NAME", ...)
OPTION = re.compile(r'\.(?:option|flag|alias)\(\s*"(-[^"]+)"')
POSITIONAL = re.compile(r'\.positional\(\s*"([^"]+)"')


def tool_names():
    return sorted(os.path.splitext(os.path.basename(p))[0]
                  for p in glob.glob(os.path.join(TOOLS_DIR, "*.cpp")))


def declared(name):
    """(options, positionals) the tool's source declares, with the shared drive options."""
    with open(os.path.join(TOOLS_DIR, name + ".cpp")) as f:
        source = f.read()
    options = set(OPTION.findall(source))
    if "addDriveSourceOptions" in source:
        with open(os.path.join(TOOLS_DIR, "support", "drive_options.h")) as f:
            options |= set(OPTION.findall(f.read()))
    return options, set(POSITIONAL.findall(source))


def run(name, *args):
    p = subprocess.run([os.path.join(BIN, name)] + list(args), stdin=subprocess.DEVNULL,
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=60)
    return p.returncode, p.stdout.decode("utf-8", "replace"), p.stderr.decode("utf-8", "replace")


_HELP = {}


def help_run(name):
    """`TOOL --help`, run once per tool (a tool starts in about a second: its shared libraries)."""
    if name not in _HELP:
        _HELP[name] = run(name, "--help")
    return _HELP[name]


@unittest.skipUnless(os.path.isdir(BIN), "the tools are not built (%s)" % BIN)
class ToolsHelp(unittest.TestCase):
    def test_every_tool_is_built(self):
        missing = [t for t in tool_names() if not os.path.isfile(os.path.join(BIN, t))]
        self.assertEqual(missing, [], "not built in %s" % BIN)

    def test_help_names_every_declared_option(self):
        for name in tool_names():
            with self.subTest(tool=name):
                options, positionals = declared(name)
                self.assertTrue(options, "%s declares no option with CommandLine" % name)
                for flag in ("--help", "-h"):
                    code, out, err = help_run(name) if flag == "--help" else run(name, flag)
                    self.assertEqual(code, 0, "%s %s: exit %d\n%s" % (name, flag, code, err))
                    self.assertTrue(out.startswith("usage: %s" % name), out[:200])
                    tokens = set(re.findall(r"[^\s,]+", out))
                    for option in sorted(options | positionals):
                        self.assertIn(option, tokens, "%s --help does not name %s" % (name, option))

    def test_unknown_option_is_a_usage_error(self):
        for name in tool_names():
            with self.subTest(tool=name):
                code, out, err = run(name, "--no-such-option")
                self.assertEqual(code, 2, "%s: exit %d\n%s%s" % (name, code, out, err))
                self.assertIn("unknown option '--no-such-option'", err)
                self.assertIn("--help", err)

    def test_missing_value_is_a_usage_error(self):
        for name in tool_names():
            with self.subTest(tool=name):
                _, out, _ = help_run(name)
                # The first option that takes a value ("  --name VALUE  description").
                match = re.search(r"^  (?:-\w, )?(--[\w-]+) [^\s-]", out, re.M)
                if match is None:  # flags and positional arguments only (mulran2bag)
                    continue
                code, _, err = run(name, match.group(1))
                self.assertEqual(code, 2, "%s %s: exit %d\n%s" % (name, match.group(1), code, err))
                self.assertIn("%s needs a value" % match.group(1), err)


if __name__ == "__main__":
    unittest.main()
