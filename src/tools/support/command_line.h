#pragma once
// CommandLine: the options of one command-line tool (src/tools/), declared once and used both to
// parse argv and to print --help, so that the help cannot drift from what is parsed.
//
//   CommandLine cli("evaluate_map", "Compares a run's map with the prior buildings.");
//   cli.option("--run", "DIR", "the offline_slam output folder", &run_dir).required();
//   cli.option("--min-z", "Z", "lowest map point used, m", &min_z);
//   cli.flag("--json", "print the report as JSON", &json);
//   if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
//
// Every tool answers -h/--help (usage on stdout, exit 0). An unknown option, a missing or
// malformed value, a missing required option or positional argument prints the error and the
// synopsis on stderr and exits with the usage-error code (2 unless set otherwise). A value
// option takes the next argument whatever it is ("--min-z -1.5"); given twice, the last wins
// unless its handler collects the values. Numbers must be whole ("10", "0.5", "1e3" for a
// double; "10x" is an error).
#include <cstddef>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace osm_graph_slam::tools {

class CommandLine {
 public:
  /// Takes an option's value; returns "" when it is accepted, else why not.
  using Handler = std::function<std::string(const std::string& value)>;

  /// `summary`: what the tool does, the first lines of --help.
  CommandLine(std::string program, std::string summary);

  /// --name VALUE kept as text only: read it with has(), value() or values().
  CommandLine& option(const std::string& name, const std::string& value_name,
                      const std::string& description);
  /// --name VALUE stored in *target; --help shows the target's initial value as the default
  /// (numbers always, text when not empty; override with defaultText()).
  CommandLine& option(const std::string& name, const std::string& value_name,
                      const std::string& description, std::string* target);
  CommandLine& option(const std::string& name, const std::string& value_name,
                      const std::string& description, int* target);
  CommandLine& option(const std::string& name, const std::string& value_name,
                      const std::string& description, double* target);
  CommandLine& option(const std::string& name, const std::string& value_name,
                      const std::string& description, std::size_t* target);
  /// --name VALUE handed to `handler` (lists, choices, repeatable options).
  CommandLine& option(const std::string& name, const std::string& value_name,
                      const std::string& description, Handler handler);
  /// --name without a value: *target = value_when_given (if target is given); has(name).
  CommandLine& flag(const std::string& name, const std::string& description, bool* target = nullptr,
                    bool value_when_given = true);
  /// --name without a value: calls `action` (e.g. when the last of several flags wins).
  CommandLine& flag(const std::string& name, const std::string& description,
                    std::function<void()> action);
  /// A positional argument, filled in declaration order by the arguments that are no option.
  CommandLine& positional(const std::string& name, const std::string& description,
                          std::string* target, bool required = true);

  /// Modifiers of the option declared last.
  CommandLine& required();
  CommandLine& defaultText(const std::string& text);
  /// Another spelling of the option declared last (e.g. "-o" for "--output").
  CommandLine& alias(const std::string& name);

  /// A paragraph printed after the options in --help (e.g. how options combine).
  CommandLine& note(const std::string& text);
  /// The exit status of a usage error (default 2).
  CommandLine& usageErrorCode(int code);

  /// Parses argv. Returns nothing when the tool should go on, else its exit status: 0 after
  /// printing --help, the usage-error code after printing an error (see fail()).
  std::optional<int> parse(int argc, char** argv);

  /// Whether the option (value option or flag, by its name with dashes) was given.
  bool has(const std::string& name) const;
  /// The last value given for a value option, else `fallback`.
  std::string value(const std::string& name, const std::string& fallback = "") const;
  /// The value options given, by name without the leading dashes ("max-scans" -> "100").
  const std::map<std::string, std::string>& values() const { return values_; }

  /// Prints "program: why", the synopsis and a pointer to --help on stderr; returns the
  /// usage-error code. For the checks a tool makes after parse().
  int fail(const std::string& why) const;

  /// The full help text (what --help prints).
  std::string help() const;
  /// The one-line synopsis: "usage: program POSITIONAL --required X [options]".
  std::string synopsis() const;

 private:
  struct Option {
    std::string name;
    std::vector<std::string> aliases;
    std::string value_name;  ///< empty for a flag
    std::string description;
    std::string default_text;
    bool required = false;
    Handler handler;  ///< value options: stores the value; flags: called with ""
  };
  struct Positional {
    std::string name;
    std::string description;
    std::string* target;
    bool required;
  };

  Option& add(const std::string& name, const std::string& value_name,
              const std::string& description, Handler handler);
  const Option* find(const std::string& spelling) const;

  std::string program_;
  std::string summary_;
  std::vector<Option> options_;
  std::vector<Positional> positionals_;
  std::vector<std::string> notes_;
  std::map<std::string, std::string> values_;
  std::vector<std::string> given_;
  int usage_error_code_ = 2;
  bool last_is_positional_ = false;
};

/// Splits "a,b,c" at the commas (empty items kept out).
std::vector<std::string> splitCommaList(const std::string& text);
/// Whole-string number parsing (no trailing characters); false on failure.
bool parseInt(const std::string& text, long long* value);
bool parseDouble(const std::string& text, double* value);

}  // namespace osm_graph_slam::tools
