#include "support/command_line.h"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <utility>

namespace osm_graph_slam::tools {

namespace {

constexpr std::size_t kNameColumn = 30;  ///< descriptions start here in --help
constexpr std::size_t kLineWidth = 100;

std::string formatDouble(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", value);
  return text;
}

/// One line of text word-wrapped to kLineWidth, every line after the first indented by `indent`.
std::string wrapLine(const std::string& text, std::size_t first_column, std::size_t indent) {
  std::istringstream words(text);
  std::string out, word;
  std::size_t column = first_column;
  bool line_start = true;
  while (words >> word) {
    if (!line_start && column + 1 + word.size() > kLineWidth) {
      out += "\n" + std::string(indent, ' ');
      column = indent;
      line_start = true;
    }
    if (!line_start) {
      out += ' ';
      ++column;
    }
    out += word;
    column += word.size();
    line_start = false;
  }
  return out;
}

/// `text` word-wrapped line by line: a line break in it is kept, and so is a line's indentation.
std::string wrap(const std::string& text, std::size_t first_column, std::size_t indent) {
  std::istringstream lines(text);
  std::string out;
  bool first = true;
  for (std::string line; std::getline(lines, line);) {
    const std::size_t lead = std::min(line.find_first_not_of(' '), line.size());
    if (!first) out += "\n" + std::string(indent, ' ');
    const std::size_t column = (first ? first_column : indent) + lead;
    out += std::string(lead, ' ') + wrapLine(line.substr(lead), column, column);
    first = false;
  }
  return out;
}

}  // namespace

bool parseInt(const std::string& text, long long* value) {
  if (text.empty()) return false;
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (errno != 0 || *end != '\0') return false;
  *value = v;
  return true;
}

bool parseDouble(const std::string& text, double* value) {
  if (text.empty()) return false;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (errno == ERANGE || *end != '\0') return false;
  *value = v;
  return true;
}

std::vector<std::string> splitCommaList(const std::string& text) {
  std::vector<std::string> items;
  std::stringstream list(text);
  for (std::string item; std::getline(list, item, ',');)
    if (!item.empty()) items.push_back(item);
  return items;
}

CommandLine::CommandLine(std::string program, std::string summary)
    : program_(std::move(program)), summary_(std::move(summary)) {}

CommandLine::Option& CommandLine::add(const std::string& name, const std::string& value_name,
                                      const std::string& description, Handler handler) {
  options_.push_back({name, {}, value_name, description, "", false, std::move(handler)});
  last_is_positional_ = false;
  return options_.back();
}

CommandLine& CommandLine::option(const std::string& name, const std::string& value_name,
                                 const std::string& description) {
  add(name, value_name, description, [](const std::string&) { return std::string(); });
  return *this;
}

CommandLine& CommandLine::option(const std::string& name, const std::string& value_name,
                                 const std::string& description, std::string* target) {
  add(name, value_name, description, [target](const std::string& v) {
    *target = v;
    return std::string();
  }).default_text = *target;
  return *this;
}

CommandLine& CommandLine::option(const std::string& name, const std::string& value_name,
                                 const std::string& description, int* target) {
  add(name, value_name, description, [target](const std::string& v) {
    long long n = 0;
    if (!parseInt(v, &n) || n < INT_MIN || n > INT_MAX) return "'" + v + "' is not an integer";
    *target = static_cast<int>(n);
    return std::string();
  }).default_text = std::to_string(*target);
  return *this;
}

CommandLine& CommandLine::option(const std::string& name, const std::string& value_name,
                                 const std::string& description, double* target) {
  add(name, value_name, description, [target](const std::string& v) {
    if (!parseDouble(v, target)) return "'" + v + "' is not a number";
    return std::string();
  }).default_text = formatDouble(*target);
  return *this;
}

CommandLine& CommandLine::option(const std::string& name, const std::string& value_name,
                                 const std::string& description, std::size_t* target) {
  add(name, value_name, description, [target](const std::string& v) {
    long long n = 0;
    if (!parseInt(v, &n) || n < 0) return "'" + v + "' is not a non-negative integer";
    *target = static_cast<std::size_t>(n);
    return std::string();
  }).default_text = std::to_string(*target);
  return *this;
}

CommandLine& CommandLine::option(const std::string& name, const std::string& value_name,
                                 const std::string& description, Handler handler) {
  add(name, value_name, description, std::move(handler));
  return *this;
}

CommandLine& CommandLine::flag(const std::string& name, const std::string& description,
                               bool* target, bool value_when_given) {
  add(name, "", description, [target, value_when_given](const std::string&) {
    if (target) *target = value_when_given;
    return std::string();
  });
  return *this;
}

CommandLine& CommandLine::flag(const std::string& name, const std::string& description,
                               std::function<void()> action) {
  add(name, "", description, [action = std::move(action)](const std::string&) {
    action();
    return std::string();
  });
  return *this;
}

CommandLine& CommandLine::positional(const std::string& name, const std::string& description,
                                     std::string* target, bool required) {
  positionals_.push_back({name, description, target, required});
  last_is_positional_ = true;
  return *this;
}

CommandLine& CommandLine::required() {
  if (last_is_positional_)
    positionals_.back().required = true;
  else if (!options_.empty())
    options_.back().required = true;
  return *this;
}

CommandLine& CommandLine::defaultText(const std::string& text) {
  if (!options_.empty()) options_.back().default_text = text;
  return *this;
}

CommandLine& CommandLine::alias(const std::string& name) {
  if (!options_.empty()) options_.back().aliases.push_back(name);
  return *this;
}

CommandLine& CommandLine::note(const std::string& text) {
  notes_.push_back(text);
  return *this;
}

CommandLine& CommandLine::usageErrorCode(int code) {
  usage_error_code_ = code;
  return *this;
}

const CommandLine::Option* CommandLine::find(const std::string& spelling) const {
  for (const auto& o : options_) {
    if (o.name == spelling) return &o;
    for (const auto& a : o.aliases)
      if (a == spelling) return &o;
  }
  return nullptr;
}

std::optional<int> CommandLine::parse(int argc, char** argv) {
  std::size_t next_positional = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help") {
      std::cout << help();
      return 0;
    }
    if (arg.size() > 1 && arg[0] == '-') {
      const Option* o = find(arg);
      if (!o) return fail("unknown option '" + arg + "'");
      std::string value;
      if (!o->value_name.empty()) {
        if (i + 1 >= argc) return fail(arg + " needs a value (" + o->value_name + ")");
        value = argv[++i];
        values_[o->name.substr(o->name.find_first_not_of('-'))] = value;
      }
      const std::string error = o->handler(value);
      if (!error.empty()) return fail(arg + ": " + error);
      given_.push_back(o->name);
      continue;
    }
    if (next_positional >= positionals_.size()) return fail("unexpected argument '" + arg + "'");
    const Positional& p = positionals_[next_positional++];
    if (p.target) *p.target = arg;
  }
  for (std::size_t k = next_positional; k < positionals_.size(); ++k)
    if (positionals_[k].required) return fail(positionals_[k].name + " is required");
  for (const auto& o : options_)
    if (o.required && !has(o.name)) return fail(o.name + " is required");
  return std::nullopt;
}

bool CommandLine::has(const std::string& name) const {
  for (const auto& g : given_)
    if (g == name) return true;
  return false;
}

std::string CommandLine::value(const std::string& name, const std::string& fallback) const {
  const auto it = values_.find(name.substr(name.find_first_not_of('-')));
  return it == values_.end() ? fallback : it->second;
}

int CommandLine::fail(const std::string& why) const {
  std::cerr << program_ << ": " << why << "\n"
            << synopsis() << "Run '" << program_ << " --help' for the options.\n";
  return usage_error_code_;
}

std::string CommandLine::synopsis() const {
  std::string line = "usage: " + program_;
  for (const auto& p : positionals_) line += p.required ? " " + p.name : " [" + p.name + "]";
  for (const auto& o : options_)
    if (o.required) line += " " + o.name + " " + o.value_name;
  line += " [options]";
  return wrap(line, 0, 7 + program_.size() + 1) + "\n";
}

std::string CommandLine::help() const {
  std::string text = synopsis() + "\n" + wrap(summary_, 0, 0) + "\n";
  auto entry = [&text](const std::string& left, const std::string& description) {
    std::string line = "  " + left;
    if (line.size() + 2 > kNameColumn)
      line += "\n" + std::string(kNameColumn, ' ');
    else
      line += std::string(kNameColumn - line.size(), ' ');
    text += line + wrap(description, kNameColumn, kNameColumn) + "\n";
  };
  if (!positionals_.empty()) {
    text += "\narguments:\n";
    for (const auto& p : positionals_)
      entry(p.name, p.description + (p.required ? "" : " (optional)"));
  }
  text += "\noptions:\n";
  for (const auto& o : options_) {
    std::string left;
    for (const auto& a : o.aliases) left += a + ", ";
    left += o.name + (o.value_name.empty() ? "" : " " + o.value_name);
    std::string description = o.description;
    if (o.required) description += " (required)";
    if (!o.default_text.empty()) description += " (default: " + o.default_text + ")";
    entry(left, description);
  }
  entry("-h, --help", "print this help and exit");
  for (const auto& n : notes_) text += "\n" + wrap(n, 0, 0) + "\n";
  return text;
}

}  // namespace osm_graph_slam::tools
