// The program's commands in one table: what dispatch finds, the driver parses and checks, and
// the program's help lists, one line each. Each command's help and work are in its own file.
#include "command.hpp"
#include "store.hpp"  // printStoreHelp, runStoreActions

namespace octovk::cli {

namespace {

const Subcommand kSubcommands[] = {
    {.name = "integrate",
     .summary = "scans (a .graph or TUM RGB-D folder) into a .bt / .ot map; colour, stamps",
     .print_help = printIntegrateHelp,
     .input = "scan graph or folder",
     .second_input_hint = "; outputs go after -o",
     .outputs = Subcommand::Outputs::kMany,
     .no_output = "no output file; add -o MAP.bt and/or -o MAP.ot",
     .output_extensions = {".bt", ".ot"},
     .output_formats = ".bt (max-likelihood binary) or .ot (full log-odds)",
     .max_device_memory = true,
     .value_options = integrateValueOptions(),
     .multi_value_options = cameraMultiValueOptions(),
     .make = makeIntegrate,
     .examples = "  octovk integrate scans.graph -o map.bt -o map.ot -r 0.05\n"
                 "  octovk integrate scans.graph -o map.bt --max-range 10 --changes changes.ply\n"
                 "  octovk integrate rgbd_dataset_freiburg1_xyz --color -o map.ot\n"},
    {.name = "convert",
     .summary = "a TUM RGB-D folder as an OctoMap scan graph (.graph)",
     .print_help = printConvertHelp,
     .input = "folder",
     .second_input_hint = "; the output goes after -o",
     .outputs = Subcommand::Outputs::kOne,
     .writes = "one scan graph",
     .no_output = "no output file; add -o SCANS.graph",
     .output_extensions = {".graph"},
     .output_formats = ".graph (an OctoMap scan graph)",
     .value_options = cameraValueOptions(),
     .multi_value_options = cameraMultiValueOptions(),
     .make = makeConvert,
     .examples = "  octovk convert rgbd_dataset_freiburg1_xyz -o scans.graph\n"
                 "  octovk convert DIR -o scans.graph --intrinsics 517.3 516.5 318.6 255.3\n"},
    {.name = "info",
     .summary = "what a map file holds: resolution, nodes, leaves, bounds, memory",
     .print_help = printInfoHelp,
     .input = "map file",
     .max_device_memory = true,
     .unknown_option_tail = "",
     .make = makeInfo,
     .examples = "  octovk info map.bt\n"
                 "  octovk info map.ot --max-device-memory 512M\n"},
    {.name = "render",
     .summary = "a PNG picture of a map's occupied cells, with height and scale bars",
     .print_help = printRenderHelp,
     .input = "map file",
     .second_input_hint = "; the picture goes after -o",
     .outputs = Subcommand::Outputs::kOne,
     .writes = "one picture",
     .no_output = "no output picture; add -o VIEW.png",
     .output_extensions = {".png"},
     .output_formats = ".png",
     .max_device_memory = true,
     .large_batches = true,
     .value_options = {"--size", "--fov", "--z-max"},
     .multi_value_options = {{"--eye", "X Y Z"}, {"--look-at", "X Y Z"}},
     .make = makeRender,
     .examples =
         "  octovk render map.bt -o view.png\n"
         "  octovk render map.bt -o view.png --eye 10 -10 8 --look-at 0 0 1 --size 1024x768\n"
         "  octovk render map.bt -o inside.png --z-max 2\n"},
    {.name = "export",
     .summary = "a map's leaf cells as an ASCII PLY point cloud",
     .print_help = printExportHelp,
     .input = "map file",
     .second_input_hint = "; the PLY file goes after -o",
     .outputs = Subcommand::Outputs::kOne,
     .writes = "one file",
     .no_output = "no output file; add -o CELLS.ply",
     .output_extensions = {".ply"},
     .output_formats = ".ply (ASCII PLY point cloud)",
     .max_device_memory = true,
     .value_options = {"--color"},
     .multi_value_options = {{"--box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"}},
     .make = makeExport,
     .examples = "  octovk export map.bt -o cells.ply --occupied-only\n"
                 "  octovk export map.bt -o box.ply --box -2 -2 0 2 2 2 --color occupancy\n"},
    {.name = "edit",
     .summary = "clear boxes of a map (octomap_server's clear_bbx) or keep only a box",
     .print_help = printEditHelp,
     .input = "map file",
     .second_input_hint = "; the edited map goes after -o",
     .outputs = Subcommand::Outputs::kOne,
     .writes = "one map",
     .no_output = "no output file; add -o OUT.bt or -o OUT.ot",
     .output_extensions = {".bt", ".ot"},
     .output_formats = ".bt or .ot (OctoMap map)",
     .max_device_memory = true,
     .multi_value_options = {{"--clear-box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"},
                             {"--keep-box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"}},
     .make = makeEdit,
     .examples = "  octovk edit map.bt --clear-box 0 0 0 1 1 2 -o cleared.bt\n"
                 "  octovk edit map.bt --keep-box -5 -5 -1 5 5 3 -o window.bt\n"},
    {.name = "distance",
     .summary = "a PNG slice of the distance field (to the nearest obstacle) in a box",
     .print_help = printDistanceHelp,
     .input = "map file",
     .second_input_hint = "; the picture goes after -o",
     .outputs = Subcommand::Outputs::kOne,
     .writes = "one picture",
     .no_output = "no output file; add -o SLICE.png",
     .output_extensions = {".png"},
     .output_formats = ".png (8-bit RGB picture)",
     .max_device_memory = true,
     .large_batches = true,
     .value_options = {"--z", "--max-distance", "--cell-pixels", "--unknown"},
     .multi_value_options = {{"--box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"}},
     .make = makeDistance,
     .examples = "  octovk distance map.bt --box -5 -5 0 5 5 2 --z 0.5 -o slice.png\n"
                 "  octovk distance map.bt --box -5 -5 0 5 5 2 --max-distance 1 --unknown free\n"
                 "                  -o optimistic.png\n"},
    {.name = "store",
     .summary = "a map store: export or follow a map, its scan log, what it holds",
     .print_help = printStoreHelp,
     .make = nullptr,
     .examples = "  octovk store export map.sqlite -o map.bt\n"
                 "  octovk store follow map.sqlite -o live.ot\n"
                 "  octovk store log map.sqlite --map lab\n",
     .run_actions = runStoreActions},
    {.name = "devices",
     .summary = "the Vulkan devices and the one octovk picks",
     .print_help = printDevicesHelp,
     .make = makeDevices,
     .examples = "  octovk devices\n"
                 "  OCTOVK_DEVICE=1 octovk devices\n"},
};

}  // namespace

std::span<const Subcommand> subcommands() { return kSubcommands; }

}  // namespace octovk::cli
