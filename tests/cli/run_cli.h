// Runs the facetree executable as a user would and captures what it says.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace facetree::test {

struct CliResult {
  int exitCode = -1;
  std::string out;  // stdout and stderr, merged
};

// Runs `command` in the shell, stdout and stderr merged.
inline CliResult runShell(const std::string& command) {
  CliResult result;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer;
  size_t got;
  while ((got = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0) result.out.append(buffer.data(), got);
  const int status = ::pclose(pipe);
  result.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

inline CliResult runCli(const std::string& arguments) {
  return runShell(std::string(FACETREE_CLI) + " " + arguments);
}

}  // namespace facetree::test
