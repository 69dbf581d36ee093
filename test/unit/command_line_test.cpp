// CommandLine (src/tools/support/command_line.h), the tools' option parser and --help.
#include "support/command_line.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

using osm_graph_slam::tools::CommandLine;

namespace {

/// argv from a list of words (argv[0] = "tool").
class Argv {
 public:
  explicit Argv(std::vector<std::string> words) : words_(std::move(words)) {
    words_.insert(words_.begin(), "tool");
    for (auto& w : words_) pointers_.push_back(w.data());
  }
  int argc() const { return static_cast<int>(pointers_.size()); }
  char** argv() { return pointers_.data(); }

 private:
  std::vector<std::string> words_;
  std::vector<char*> pointers_;
};

struct Parsed {
  std::string run, input;
  double min_z = 1.5;
  int n = 3;
  size_t max_scans = 0;
  bool json = false, use_osm = true;
  std::vector<std::string> sets;
};

CommandLine declare(Parsed& p) {
  CommandLine cli("tool", "Does a thing.");
  cli.positional("INPUT", "what to read", &p.input, false)
      .option("--run", "DIR", "the run", &p.run)
      .required()
      .option("--min-z", "Z", "lowest point", &p.min_z)
      .option("--count", "N", "how many", &p.n)
      .alias("-n")
      .option("--max-scans", "N", "at most N scans", &p.max_scans)
      .defaultText("all")
      .option("--set", "key=value", "an override; repeatable",
              [&p](const std::string& kv) {
                if (kv.find('=') == std::string::npos) return "expects key=value, got '" + kv + "'";
                p.sets.push_back(kv);
                return std::string();
              })
      .option("--config", "FILE", "overrides, kept as text")
      .flag("--json", "JSON", &p.json)
      .flag("--no-osm", "without OSM", &p.use_osm, false)
      .note("A note.");
  return cli;
}

}  // namespace

TEST(CommandLine, ParsesValuesFlagsAliasesAndPositionals) {
  Parsed p;
  CommandLine cli = declare(p);
  Argv a({"in.bag", "--run", "r", "--min-z", "-1.5", "-n", "7", "--max-scans", "20", "--json",
          "--no-osm", "--set", "a=1", "--set", "b/c=2", "--config", "x.yaml", "--run", "r2"});
  EXPECT_FALSE(cli.parse(a.argc(), a.argv()));
  EXPECT_EQ(p.input, "in.bag");
  EXPECT_EQ(p.run, "r2") << "the last value wins";
  EXPECT_DOUBLE_EQ(p.min_z, -1.5) << "a value may start with '-'";
  EXPECT_EQ(p.n, 7);
  EXPECT_EQ(p.max_scans, 20u);
  EXPECT_TRUE(p.json);
  EXPECT_FALSE(p.use_osm);
  EXPECT_EQ(p.sets, (std::vector<std::string>{"a=1", "b/c=2"}));
  EXPECT_TRUE(cli.has("--config"));
  EXPECT_TRUE(cli.has("--count")) << "an alias counts as its option";
  EXPECT_FALSE(cli.has("--nothing"));
  EXPECT_EQ(cli.value("--config"), "x.yaml");
  EXPECT_EQ(cli.value("config"), "x.yaml");
  EXPECT_EQ(cli.value("--missing", "fallback"), "fallback");
  EXPECT_EQ(cli.values().at("max-scans"), "20");
  EXPECT_EQ(cli.values().at("run"), "r2");
}

TEST(CommandLine, HelpIsGeneratedFromTheDeclarations) {
  Parsed p;
  CommandLine cli = declare(p);
  const std::string help = cli.help();
  EXPECT_EQ(help.rfind("usage: tool [INPUT] --run DIR [options]\n", 0), 0u) << help;
  for (const char* text :
       {"Does a thing.", "--run DIR", "(required)", "--min-z Z", "(default: 1.5)", "-n, --count N",
        "(default: 3)", "(default: all)", "--set key=value", "--json", "--no-osm", "-h, --help",
        "A note.", "INPUT", "(optional)"})
    EXPECT_NE(help.find(text), std::string::npos) << text << "\n" << help;
  EXPECT_EQ(help.find("(default: 0)"), std::string::npos) << "--max-scans shows 'all'";

  Argv a({"--help"});
  testing::internal::CaptureStdout();
  const auto exit_code = cli.parse(a.argc(), a.argv());
  const std::string out = testing::internal::GetCapturedStdout();
  ASSERT_TRUE(exit_code);
  EXPECT_EQ(*exit_code, 0);
  EXPECT_EQ(out, help);
}

TEST(CommandLine, BadCommandLinesAreUsageErrors) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--run", "r", "--bogus"}, "unknown option '--bogus'"},
      {{"--run"}, "--run needs a value (DIR)"},
      {{"--min-z", "1"}, "--run is required"},
      {{"--run", "r", "--count", "3x"}, "--count: '3x' is not an integer"},
      {{"--run", "r", "--min-z", "low"}, "--min-z: 'low' is not a number"},
      {{"--run", "r", "--max-scans", "-1"}, "--max-scans: '-1' is not a non-negative integer"},
      {{"--run", "r", "--set", "a"}, "--set: expects key=value, got 'a'"},
      {{"--run", "r", "a", "b"}, "unexpected argument 'b'"}};
  for (const auto& [words, message] : cases) {
    Parsed p;
    CommandLine cli = declare(p);
    Argv a(words);
    testing::internal::CaptureStderr();
    const auto exit_code = cli.parse(a.argc(), a.argv());
    const std::string err = testing::internal::GetCapturedStderr();
    ASSERT_TRUE(exit_code) << message;
    EXPECT_EQ(*exit_code, 2) << message;
    EXPECT_NE(err.find("tool: " + message), std::string::npos) << err;
    EXPECT_NE(err.find("usage: tool"), std::string::npos) << err;
  }
  Parsed p;
  CommandLine cli = declare(p);
  cli.usageErrorCode(1);
  Argv a({"--bogus"});
  testing::internal::CaptureStderr();
  const auto exit_code = cli.parse(a.argc(), a.argv());
  testing::internal::GetCapturedStderr();
  ASSERT_TRUE(exit_code);
  EXPECT_EQ(*exit_code, 1);
}

TEST(CommandLine, CommaLists) {
  using osm_graph_slam::tools::splitCommaList;
  EXPECT_EQ(splitCommaList("a,b,,c"), (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_TRUE(splitCommaList("").empty());
}
