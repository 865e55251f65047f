// The cluster file subcommands (cli/cmd_fch.cpp): facetree truncate, info and verify. Each
// returns an exit code (cli/args.h); a corrupt or unreadable cluster file gives kExitInput
// with one line "facetree: FILE: REASON" on stderr.
#pragma once

#include <string>
#include <vector>

#include "facetree/io.h"

namespace facetree::cli {

class Args;
class SignalGuard;

// The reader of a cluster file command: --memory (default the cap the file was built under, else
// the build's default) and --tmp.
ReaderOptions readerOptions(const Args& args);

// truncate IN.fch -o OUT.fch (--nodes N | --max-bytes B)
int runTruncate(const std::vector<std::string>& args, SignalGuard& signals);
// info FILE.fch [--json]
int runInfo(const std::vector<std::string>& args);
// verify FILE.fch [MESH] [--json]: exit 3 with the first violation when the file is invalid.
int runVerify(const std::vector<std::string>& args);

}  // namespace facetree::cli
