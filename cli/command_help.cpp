// The commands' help and option tables (command_help.h).
#include "command_help.h"

#include <algorithm>
#include <map>
#include <set>
#include <stdexcept>

namespace facetree::cli {
namespace {

std::vector<CommandHelp> makeCommands();

// The options of the commands that read a cluster file lazily (ClusterFileReader), after `options`.
std::vector<OptionHelp> withReaderOptions(std::vector<OptionHelp> options) {
  options.push_back({"memory", "SIZE", "",
                     "read under this cap (default the cap the file was built under, else half the RAM): a "
                     "quarter caches frames, a quarter holds a pass over the nodes, whose rest goes to a "
                     "temporary file"});
  options.push_back({"tmp", "DIR", "", "where that temporary file goes (default the system's)"});
  return options;
}

const std::vector<CommandHelp>& commands() {
  static const std::vector<CommandHelp> table = makeCommands();
  return table;
}

// The stage commands: the out-of-core build as tasks over a work directory. `stage plan` takes the
// options of `build` that a cluster file's build uses.
void addStageCommands(std::vector<CommandHelp>& table) {
  const CommandHelp& build = table[1];
  std::vector<OptionHelp> planOptions = {
      {"work", "DIR", "", "the work directory the tasks share (created; the caller removes it)"},
      {"cell-tasks", "N", "",
       "cells tasks to cut the cells into (default one per 16 cells); the file does not depend on it"},
      {"read-tasks", "N", "",
       "read tasks of a binary PLY or STL read in ranges (default one per 2^20 faces; an STL at least "
       "one per 12 bytes a face in an eighth of --memory); the file does not depend on it"},
      {"node-tasks", "N", "",
       "node tasks of the write (default one per 2^20 node positions); the file does not depend on it"}};
  for (const OptionHelp& o : build.options) {
    const std::string name = o.name;
    if (name == "mesh-out" || name == "draco-bits" || name == "method" || name == "leaf-size" ||
        name == "no-boxes")
      continue;
    planOptions.push_back(o);
  }
  table.push_back(
      {"stage plan", "MESH --work DIR -o OUT.fch [options]",
       "plan a build run as tasks over a work directory: its first task",
       "The out-of-core build as tasks of an engine (Dask, a Slurm job array) over a work directory that\n"
       "every task sees. `stage plan` prints the steps that follow, each a number of tasks that run in\n"
       "any order, anywhere, once the step before is done: a binary PLY whose faces are triangles in\n"
       "records of one size, or a binary STL, is read in ranges (`stage read`, `stage count`, for an\n"
       "STL `stage weld`, then `stage grid`, which prints `stage bin`, `stage cells` and `stage\n"
       "upper`); any other mesh is read and binned by the\n"
       "plan (then `stage cells` and `stage upper`). `stage upper` prints `stage geometry` and `stage\n"
       "boxes` (which prints `stage nodes` and `stage layout`), or with compact boxes all three;\n"
       "`stage layout` prints `stage place` and `stage finish`. OUT.fch is the bytes\n"
       "`facetree build` writes with the same options. Each task writes under temporary names and\n"
       "renames when complete: a task rerun gives the same files, and a task already done is skipped.\n"
       "A plan of the same job (input, its size and time, options) already in DIR stands; another one\n"
       "replaces it and every task's outputs. A mesh that fits --memory in core is built by the plan;\n"
       "then only the finish follows.",
       planOptions});
  const auto taskCommand = [&](const char* name, const char* about, const char* details) {
    table.push_back({name,
                     "--work DIR --task I [--json]",
                     about,
                     details,
                     {{"work", "DIR", "", "the work directory of `stage plan`"},
                      {"task", "I", "", "the task, 0 to the step's count less one"},
                      {"json", "", "", "print the result as one JSON object"}}});
  };
  // The range steps' tasks can share the cap: a scheduler runs several at once on one machine.
  const auto rangeTaskCommand = [&](const char* name, const char* about, const char* details) {
    taskCommand(name, about, details);
    table.back().synopsis = "--work DIR --task I [--alongside N] [--json]";
    table.back().options.insert(
        table.back().options.end() - 1,
        {"alongside", "N", "",
         "N tasks of the step run at once on this machine, this one among them (default 1): "
         "the task takes one thread and half the plan's cap over N for its "
         "buffers, so that together they hold the cap (the same outputs)"});
  };
  rangeTaskCommand(
      "stage read", "read one range of a binary PLY or STL: its box and counts",
      "Reads the plan's options from DIR; holds the plan's --memory. Every read task must be done\n"
      "before any count task.");
  rangeTaskCommand(
      "stage count", "count one range's faces by cell bin",
      "Reads the plan's options from DIR; holds the plan's --memory. Every count task must be done\n"
      "before the weld tasks (an STL) or the grid. An STL's count task also files its corners by\n"
      "position for the weld tasks.");
  taskCommand("stage weld", "number one part of an STL's distinct corner positions",
              "Reads the plan's options from DIR; holds the plan's --memory. The corners of every range\n"
              "whose positions fall in the task's part are sorted, and each distinct position numbered\n"
              "as `facetree build` welds them. Every weld task must be done before the grid.");
  table.push_back({"stage grid",
                   "--work DIR [--json]",
                   "cut a mesh read in ranges into cells, and plan the bin and cells tasks",
                   "Sums the count tasks' bins and prints the steps that follow: bin, cells, finish.",
                   {{"work", "DIR", "", "the work directory of `stage plan`"},
                    {"json", "", "", "print the result as one JSON object"}}});
  rangeTaskCommand(
      "stage bin", "put one range's faces into their cells",
      "Reads the plan's options from DIR; holds the plan's --memory. Every bin task must be done\n"
      "before any cells task.");
  taskCommand("stage cells", "build the cells of one cells task of a planned build",
              "Reads the plan's options from DIR; holds the plan's --memory. Every bin task (of a mesh read\n"
              "in ranges) must be done first.");
  table.push_back(
      {"stage upper",
       "--work DIR [--json]",
       "join the cells above them and plan the write",
       "Every cells task must be done. Merges the cells' leaf clusters above them, orders the file's\n"
       "nodes, writes the plan of the geometry and node tasks, and prints the steps that follow:\n"
       "geometry and boxes (compact boxes: geometry, nodes and layout).",
       {{"work", "DIR", "", "the work directory of `stage plan`"},
        {"json", "", "", "print the result as one JSON object"}}});
  taskCommand("stage geometry",
              "write the frames of one range of the file's triangles and vertices as a piece",
              "Reads the plan's options from DIR; holds the plan's --memory. The upper step must be done.\n"
              "With exact boxes it also accumulates its part of the upper nodes' boxes.");
  table.push_back({"stage boxes",
                   "--work DIR [--json]",
                   "merge the geometry tasks' parts of the upper nodes' boxes",
                   "Every geometry task must be done. Prints the steps that follow: nodes, layout.",
                   {{"work", "DIR", "", "the work directory of `stage plan`"},
                    {"json", "", "", "print the result as one JSON object"}}});
  taskCommand("stage nodes", "write the frames of one range of the file's nodes as a piece",
              "Reads the plan's options from DIR; holds the plan's --memory. The upper step (with exact\n"
              "boxes, the boxes step) must be done.");
  table.push_back({"stage layout",
                   "--work DIR [--json]",
                   "lay out the cluster file of the pieces and write its header and index",
                   "Every geometry and node task must be done. Prints the steps that follow: place, finish.",
                   {{"work", "DIR", "", "the work directory of `stage plan`"},
                    {"json", "", "", "print the result as one JSON object"}}});
  taskCommand("stage place", "copy one piece's frames into the cluster file being laid out",
              "The layout must be done. Each place task syncs what it wrote.");
  table.push_back({"stage finish",
                   "--work DIR [--json]",
                   "give the placed cluster file of a planned build its name",
                   "Every place task must be done. Prints the report `facetree build` prints.",
                   {{"work", "DIR", "", "the work directory of `stage plan`"},
                    {"json", "", "", "print the report as one JSON object"}}});
  // The tiles as tasks: `stage tiles-plan` takes the options of `tiles` but the threads.
  std::vector<OptionHelp> tileOptions = {
      {"work", "DIR", "", "the work directory the tasks share (created; the caller removes it)"},
      {"tasks", "N", "",
       "subtrees to make as tasks (default one per 2^21 faces, at least 4); the tiles do not depend on it"}};
  for (const CommandHelp& c : table)
    if (std::string_view(c.name) == "tiles")
      for (const OptionHelp& o : c.options)
        if (std::string_view(o.name) != "threads") tileOptions.push_back(o);
  table.push_back(
      {"stage tiles-plan", "FILE.fch --work DIR -o TILES [options]",
       "plan the tiles of a cluster file as tasks over a work directory: their first task",
       "`facetree tiles` as tasks of an engine (Dask, a Slurm job array) over a work directory that every\n"
       "task sees: the plan chooses the tiles, finds where they meet and cuts the tree into subtrees;\n"
       "`stage tiles --task I` makes a subtree's tiles (any order, anywhere, each under --memory);\n"
       "`stage tiles-finish` makes the tiles above them and puts TILES in place. TILES is the bytes\n"
       "`facetree tiles` writes with the same options. A plan of the same tiles (file, its size and time,\n"
       "options) already in DIR stands, with the tasks it has done; another one replaces it.",
       tileOptions});
  rangeTaskCommand(
      "stage tiles", "make the tiles of one subtree of a planned tileset",
      "Reads the plan from DIR; holds the plan's --memory. A task done for this plan is skipped.");
  table.back().options[0].text = "the work directory of `stage tiles-plan`";
  table.back().options[2].text =
      "N tasks run at once on this machine, this one among them (default 1; at most the plan's "
      "range_tasks_at_once): they share the cap (the same tiles)";
  table.push_back({"stage tiles-finish",
                   "--work DIR [--json]",
                   "make the tiles above the subtrees and put the planned tileset in place",
                   "Every tiles task must be done. Prints the report `facetree tiles` prints.",
                   {{"work", "DIR", "", "the work directory of `stage tiles-plan`"},
                    {"json", "", "", "print the report as one JSON object"}}});
}

std::vector<CommandHelp> makeCommands() {
  std::vector<CommandHelp> table = {
      {"stats",
       "MESH [--json]",
       "counts, bounding box and read throughput of a mesh",
       "Reads MESH once without keeping it (any size) and prints its format, declared and read counts,\n"
       "bounding box and read throughput.",
       {{"json", "", "", "print the report as one JSON object"}}},
      {"build",
       "MESH [-o OUT.fch] [options]",
       "build the face cluster hierarchy, print its statistics",
       "Clusters MESH by greedy dual-edge merging under Willmott's cost (eFit + k area) perim^2 / projArea,\n"
       "gives every node an oriented box, and writes the cluster file OUT.fch (docs/FORMAT.md): nodes by\n"
       "decreasing effective cost, so that any prefix is a valid, truncated hierarchy. The job runs in\n"
       "core when the mesh fits the memory cap, else out of core in cells with temporary files.\n"
       "The output does not depend on --threads.",
       {{"output", "OUT.fch", "-o", "the cluster file; - writes it to standard output"},
        {"json", "", "", "print the report as one JSON object (stage times, peaks, sizes)"},
        {"branching", "2|4|8", "", "most children a node of the file may have (default 2)"},
        {"recast", "largest-area|fewest-nodes", "",
         "how binary nodes are merged into b-ary ones (default largest-area)"},
        {"metric", "willmott|garland|constant", "", "the merge cost (default willmott)"},
        {"k", "K", "", "the area weight of Willmott's cost (default 1e-4)"},
        {"flat-threshold", "T", "",
         "eq. 78's flatness below which a cluster's frame is its plane's (default 0.5)"},
        {"w-fit", "W", "", "Garland's fit weight (--metric garland; default 1)"},
        {"w-dir", "W", "", "Garland's orientation weight (--metric garland; default 1)"},
        {"w-shape", "W", "", "Garland's shape weight (--metric garland; default 1)"},
        {"balance-slack", "A", "",
         "raise the cost of a merge whose subtree is taller than A (ceil(log2 n) + 1) for its n faces "
         "(default 1.5; 0: off, eq. 84 alone)"},
        {"order", "rounds|exact", "",
         "rounds of reciprocal cheapest pairs (default, parallel), or the exact global greedy (the "
         "reference)"},
        {"boxes", "exact|compact", "",
         "boxes exact in their stored frame (default), or quantised against their parent's in 8 bits a "
         "face (smaller files; a box always contains its faces)"},
        {"no-boxes", "", "", "skip the boxes (no cluster file; statistics only)"},
        {"top", "N", "",
         "the last N clusters (default 64, at most one per 64 faces) merge by the least increase of the "
         "fit (the sum of area x eFit), so that the file's first nodes are the cuts that fit best; 0: "
         "eq. 84's order to the root"},
        {"threads", "N", "",
         "threads of the merge rounds, the box phase and the out-of-core cells (default 0: all cores, at "
         "most 8)"},
        {"memory", "SIZE", "",
         "the whole job under this cap (e.g. 256M; default half the RAM): in core when it fits, else (with "
         "-o, no --mesh-out) out of core"},
        {"tmp", "DIR", "", "where the out-of-core job's temporary files go (default the system's)"},
        {"max-tmp", "SIZE", "", "fail (exit 5) rather than let the temporary files pass SIZE"},
        {"cell-faces", "N", "", "out of core with cells of at most N faces, whatever the cap (needs -o)"},
        {"zstd-level", "L", "", "zstd level of the file's frames, 1 to 19 (default 3; needs -o)"},
        {"weld", "", "", "merge vertices at identical positions before clustering (STL always is)"},
        {"mesh-out", "REORDERED.ply|.drc", "", "also write the mesh with its faces in the file's order"},
        {"draco-bits", "B", "",
         "position quantisation bits of a .drc --mesh-out, 0 (lossless, the default) to 30"},
        {"method", "cluster|octree", "",
         "octree: the baseline tightest-fit octree volume clustering (time, nodes, height; no file)"},
        {"leaf-size", "N", "", "most faces in an octree leaf, 1 to 1000000 (--method octree)"}}},
      {"gen",
       "KIND -o OUT.ply|OUT.stl [options]",
       "synthetic test meshes, or a mesh subdivided",
       "KIND is grid, sphere, terrain, strip, assembly or tiled (-n TRIANGLES), or subdivide MESH\n"
       "(--levels L): midpoint subdivision, every triangle into 4^L. tiled is the terrain as a scan\n"
       "delivered in 9 x 9 unwelded tiles of 6 to 11 pieces (two material groups, a hole, islands).\n"
       "Shuffles make the dirty orders of real files.\n"
       "A name ending in .stl gets a binary STL: every triangle with its own corners, as CAD exports\n"
       "them (made of the PLY, written beside it first).",
       {{"output", "OUT", "-o", "the mesh written: binary PLY, or binary STL for a name ending in .stl"},
        {"triangles", "N", "-n", "about how many triangles (every kind but subdivide)"},
        {"levels", "L", "", "subdivision levels, 1 to 8 (subdivide)"},
        {"seed", "S", "", "seed of the shuffles and of the random kinds"},
        {"shuffle-vertices", "", "", "store the vertices in random order"},
        {"shuffle-faces", "", "", "store the faces in random order"}}},
      {"truncate", "IN.fch -o OUT.fch (--nodes N | --max-bytes B) [--json] [--memory SIZE]",
       "keep the first nodes of a cluster file",
       "Keeps the first nodes, the cheapest merges dropped first; the kept records are copied unchanged\n"
       "and the geometry kept whole. Streams: frames are copied a frame at a time, and only the last\n"
       "partial node frame is decoded.",
       withReaderOptions(
           {{"output", "OUT.fch", "-o", "the truncated file"},
            {"nodes", "N", "", "keep N nodes"},
            {"max-bytes", "B", "", "keep the most nodes whose file, geometry included, fits in B bytes"},
            {"json", "", "", "print the result as one JSON object"}})},
      {"info", "FILE.fch [--json] [--fit-cuts N,N...] [--memory SIZE]",
       "counts, height, branching histogram, bytes per section",
       "Reads the header, the frame index and the node frames in one pass; the geometry only for\n"
       "--fit-cuts.",
       withReaderOptions(
           {{"json", "", "", "print the report as one JSON object"},
            {"fit-cuts", "N,N...", "",
             "the fit error of cuts of N clusters (sum of eq. 84's eFit and of area * eFit over the cut) and "
             "the sum of the cut's box areas against N runs of the faces in Morton order, and its balance: "
             "the clusters under 1% of the average cluster's area"}})},
      {"verify", "FILE.fch [MESH] [--json] [--memory SIZE]",
       "check every invariant of a cluster file (exit 3 names the first violation)",
       "Checks the checksums, the tree, the face ranges, the costs' order and every box against its faces;\n"
       "with MESH also that the file's geometry is that mesh's. Streams: the nodes in one pass, then the\n"
       "faces in order with the nodes over each face, and the mesh's triangles against the file's by\n"
       "original id, in windows that spill to --tmp.",
       withReaderOptions({{"json", "", "", "print the result as one JSON object"}})},
      {"render", "FILE.fch (--cut N | --depth D | --raycast) -o OUT.png [options]",
       "flat-shaded picture of the clusters of a cut, or of the surface by ray casting", "",
       withReaderOptions(
           {{"output", "OUT.png", "-o", "the picture"},
            {"cut", "N", "", "the cut of N clusters from the top (default 64)"},
            {"depth", "D", "", "the cut at depth D"},
            {"raycast", "", "",
             "one ray per pixel through the hierarchy (the queries of facetree/query.h), grey by "
             "the hit triangle's angle to the view; prints the rays' box and triangle tests"},
            {"threads", "N", "", "threads of --raycast (default all cores, at most 8)"},
            {"width", "W", "", "pixels, 16 to 16384 (default 1024)"},
            {"height", "H", "", "pixels, 16 to 16384 (default 768)"},
            {"view", "X,Y,Z", "", "viewing direction (default a three-quarter view)"},
            {"up", "X,Y,Z", "", "up vector (default 0,0,1)"}})},
      {"export", "FILE.fch (--cut N | --depth D) -o OUT.ply",
       "the mesh with a colour per cluster of a cut (MeshLab)", "",
       withReaderOptions({{"output", "OUT.ply", "-o", "the coloured mesh"},
                          {"cut", "N", "", "the cut of N clusters from the top (default 64)"},
                          {"depth", "D", "", "the cut at depth D"}})},
      {"tiles", "FILE.fch -o DIR [--tile-faces N] [--draco] [--memory SIZE] [--threads N] [--json]",
       "3D Tiles 1.1 with levels of detail for viewers (CesiumJS, 3DTilesRendererJS)",
       "Writes DIR/tileset.json and one glb per tile under DIR/tiles/. Leaf tiles are the highest nodes\n"
       "of at most N faces at full resolution; an inner tile is a node whose content is its children's\n"
       "simplified to about N faces with the points it shares with other tiles and the file's own cracks\n"
       "locked, so levels meet without cracks; its geometric error, in the model's units, is above every\n"
       "child's and counts how far the mesh's own boundaries moved. Bottom-up in one pass under\n"
       "--memory, which can make tiles smaller; the same bytes for every thread count. An existing DIR is\n"
       "replaced only if it holds a tileset.json.",
       withReaderOptions(
           {{"output", "DIR", "-o", "the tileset's directory"},
            {"tile-faces", "N", "",
             "faces of a leaf tile at most, and of an inner tile's content about (default 65536)"},
            {"draco", "", "", "compress each glb's mesh with KHR_draco_mesh_compression"},
            {"draco-bits", "B", "",
             "Draco's position bits over the model's bounding cube, 8 to 30 (default 16)"},
            {"tiles-per-json", "N", "", "a subtree of more tiles goes to an external tileset (default 8192)"},
            {"threads", "N", "", "worker threads (default all cores, at most 8)"},
            {"json", "", "", "print the report as one JSON object"}})},
      {"cut", "FILE.fch (--clusters N | --max-cost C | --depth D) [-o OUT.npz] [--mesh-out OUT.ply]",
       "the clusters of a cut as JSON lines or NumPy arrays, for scripts downstream",
       "One line per cluster in face order: its position in the cut, its node (null for a single face\n"
       "or a gap that truncation left), its first face and triangle count in the file's face order, and\n"
       "the node's cost, area, perimeter and oriented box (centre, half extents, orientation x, y, z, w).\n"
       "--clusters N: the shortest prefix of the file whose cut has at least N clusters; --max-cost C:\n"
       "the cut below every node whose effective cost exceeds C; --depth D: the cut below depth D.",
       withReaderOptions(
           {{"clusters", "N", "", "the cut of at least N clusters from the top"},
            {"max-cost", "C", "", "the cut below the nodes of effective cost above C"},
            {"depth", "D", "", "the cut below the nodes of depth D and less (the root's is 1)"},
            {"output", "OUT.npz", "-o",
             "the clusters as NumPy arrays instead (numpy.load): node (-1 for none), first, triangles, "
             "cost, area, perimeter, center, half_extents, orientation; NaN where there is no node"},
            {"mesh-out", "OUT.ply", "",
             "also the mesh (every vertex of the file, its triangles in face order) with a colour and a "
             "uint cluster per face"}})},
  };
  addStageCommands(table);
  return table;
}

// Text wrapped to `width` columns, every line after the first indented by `indent`.
std::string wrap(const std::string& text, size_t indent, size_t width) {
  std::string out, line;
  size_t at = 0;
  while (at < text.size()) {
    const size_t space = text.find(' ', at);
    const std::string word = text.substr(at, space == std::string::npos ? std::string::npos : space - at);
    at = space == std::string::npos ? text.size() : space + 1;
    if (!line.empty() && indent + line.size() + 1 + word.size() > width) {
      out += line + "\n" + std::string(indent, ' ');
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  return out + line;
}

}  // namespace

const CommandHelp& commandHelp(std::string_view name) {
  for (const CommandHelp& c : commands())
    if (name == c.name) return c;
  throw std::out_of_range("no command '" + std::string(name) + "'");
}

std::string commandUsage(const CommandHelp& c) {
  std::string out = "usage: facetree " + std::string(c.name) + " " + c.synopsis + "\n\n" + c.about + ".\n";
  if (*c.details) {
    out += '\n';
    out += c.details;
    out += '\n';
  }
  out += "\noptions:\n";
  constexpr size_t kColumn = 34, kWidth = 100;
  auto row = [&](const std::string& left, const std::string& text) {
    std::string line = "  " + left;
    if (line.size() + 2 > kColumn)
      line += "\n" + std::string(kColumn, ' ');
    else
      line.append(kColumn - line.size(), ' ');
    out += line + wrap(text, kColumn, kWidth) + "\n";
  };
  for (const OptionHelp& o : c.options) {
    std::string left;
    if (*o.alias) {
      left += o.alias;
      left += ", ";
    }
    left += "--";
    left += o.name;
    if (*o.value) {
      left += ' ';
      left += o.value;
    }
    row(left, o.text);
  }
  row("-h, --help", "print this help and exit");
  return out;
}

std::string overviewUsage() {
  std::string out =
      "usage: facetree COMMAND [OPTIONS]\n\n"
      "Face cluster hierarchies over very large triangle meshes (PLY, OBJ, STL, Draco; any .zst).\n\n"
      "commands:\n";
  for (const CommandHelp& c : commands())
    out += "  " + std::string(c.name) + " " + c.synopsis + "\n      " + c.about + "\n";
  out +=
      "\n`facetree COMMAND --help` lists the command's options.\n"
      "MESH may be - for standard input; the format is detected from the content.\n\n"
      "exit codes: 0 success, 1 internal error, 2 usage, 3 bad or unreadable input,\n"
      "            4 cannot write output, 5 out of memory or over a limit,\n"
      "            130/143/129 interrupted by SIGINT/SIGTERM/SIGHUP (no output left behind)\n";
  return out;
}

std::string stageUsage() {
  std::string out =
      "usage: facetree stage "
      "plan|read|count|weld|grid|bin|cells|upper|geometry|boxes|nodes|layout|place|finish|"
      "tiles-plan|tiles|tiles-finish [OPTIONS]\n\nA build, or the tiles of a cluster file, run as tasks "
      "over a work directory:\n";
  for (const CommandHelp& c : commands())
    if (std::string_view(c.name).rfind("stage ", 0) == 0)
      out += "  " + std::string(c.name) + " " + c.synopsis + "\n      " + c.about + "\n";
  return out + "\n`facetree stage COMMAND --help` lists the command's options.\n";
}

Args parseCommand(std::string_view name, const std::vector<std::string>& argv) {
  std::set<std::string> valued, flags;
  std::map<std::string, std::string> aliases;
  for (const OptionHelp& o : commandHelp(name).options) {
    (*o.value ? valued : flags).insert(o.name);
    if (*o.alias) aliases[o.alias] = "--" + std::string(o.name);
  }
  return Args(argv, valued, flags, aliases);
}

bool asksForHelp(const std::vector<std::string>& argv) {
  return std::any_of(argv.begin(), argv.end(),
                     [](const std::string& a) { return a == "--help" || a == "-h"; });
}

}  // namespace facetree::cli
