// Every command's options in one table: what `facetree COMMAND --help` prints and what the
// command's parser accepts are the same list, so no option goes undocumented.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "args.h"

namespace facetree::cli {

struct OptionHelp {
  const char* name;   // long name without the dashes
  const char* value;  // what it takes, as help prints it ("SIZE", "2|4|8"); empty for a flag
  const char* alias;  // a short alias ("-o") or empty
  const char* text;   // what it does, one or more sentences
};

struct CommandHelp {
  const char* name;                 // as typed: "build", "stage cells"
  const char* synopsis;             // the arguments after the name
  const char* about;                // one line for the overview
  const char* details;              // paragraphs for the command's own help, or empty
  std::vector<OptionHelp> options;  // besides --help
};

// The command called `name`; std::out_of_range for an unknown one.
const CommandHelp& commandHelp(std::string_view name);
// `facetree NAME --help`: usage, what it does, every option.
std::string commandUsage(const CommandHelp& command);
// `facetree --help`: every command's synopsis and one line, the exit codes.
std::string overviewUsage();
// `facetree stage --help`: the stage commands' synopses and one line each.
std::string stageUsage();

// The command's arguments parsed against its table (UsageError for an option it does not take).
Args parseCommand(std::string_view name, const std::vector<std::string>& argv);
// Whether the arguments ask for help (--help or -h anywhere).
bool asksForHelp(const std::vector<std::string>& argv);

}  // namespace facetree::cli
