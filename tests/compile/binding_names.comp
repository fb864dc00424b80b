#version 460
#extension GL_GOOGLE_include_directive : require
// Compiled (not run) by ctest (octovk_bindings_leave_local_names_alone): the bindings'
// buffer names are macros, and a local of the same spelling must not be rewritten into a buffer
// access. Every lower-case name a buffer had is a local here.
#include "cell_set.glsl"
#include "tree.glsl"

void main() {
  uint points = 1u, hash_keys = 2u, hash_flags = 3u, nodes = 4u, block_parent = 5u;
  uint free_stack = 6u, cells = 7u, touched = 8u, prefix_blocks = 9u, leaf_boxes = 10u;
  uint endpoint_keys = 11u, walks = 12u, slots = 13u, cell_list = 14u, depth_image = 15u;
  uint change_table = 16u;
  counters.status = points + hash_keys + hash_flags + nodes + block_parent + free_stack + cells +
                    touched + prefix_blocks + leaf_boxes + endpoint_keys + walks + slots +
                    cell_list + depth_image + change_table;
}
