#version 450
#extension GL_GOOGLE_include_directive : require
// Layout probe for tests/layout_test.cpp, never run by the library: one invocation writes a
// distinct marker into every field of every shared struct through the shared bindings (element 0
// and 1 of the arrays, for the stride), and copies the push constants and a few constants out, so
// the test can check that each lands at its C++ offsetof. Marker of field `id`: uint
// 0xC0DE0000 + id, float id + 0.5, double id + 0.25, uint64 0xC0DE0000C0DE0000 + id.
#include "bindings.glsl"

// The push range, seen as one of the passes' structs (all four uints).
layout(push_constant) uniform PushBlock { RayKeysConstants pc; };

// The query bindings, which each query pass views its own way: here every query struct at once
// (two elements each, for the stride), then every pass's push-constant struct (std430 lays out a
// struct of four uints as a push block does).
layout(std430, binding = kBindQueryIn) buffer QueryInBuf {
  RayQuery probe_rays[2];
  BoxQuery probe_box;
  RayState probe_states[2];
};
layout(std430, binding = kBindQueryOut) buffer QueryOutBuf {
  LookupResult probe_lookups[2];
  RayResult probe_ray_results[2];
  NoConstants probe_no_constants;
  ClearSetsConstants probe_clear_sets;
  TransformPointsConstants probe_transform_points;
  DiscretizeConstants probe_discretize;
  RayKeysConstants probe_ray_keys;
  UnprojectConstants probe_unproject;
  PruneConstants probe_prune;
  LeafBoxesConstants probe_leaf_boxes;
  LookupConstants probe_lookup;
  CastRayConstants probe_cast_ray;
  DeviceProbeConstants probe_device_probe;
};
// The saved ray walks of the ray-key pass.
#define probe_walks WALKS

uint mu(uint id) { return 0xC0DE0000u + id; }
float mf(uint id) { return float(id) + 0.5; }
double md(uint id) { return double(id) + 0.25lf; }
uint64_t m64(uint id) { return 0xC0DE0000C0DE0000ul + uint64_t(id); }

void probeNode(uint i, uint id) {
  NODES[i].log_odds = mf(id);
  NODES[i].link = mu(id + 1u);
}

void probeActiveCell(uint i, uint id) {
  CELLS[i].slot = mu(id);
  CELLS[i].node = mu(id + 1u);
  CELLS[i].parent = mu(id + 2u);
  CELLS[i].depth = mu(id + 3u);
}

void probeNewBlock(uint i, uint id) {
  PREFIX_BLOCKS[i].node = mu(id);
  PREFIX_BLOCKS[i].source = mu(id + 1u);
  PREFIX_BLOCKS[i].block = mu(id + 2u);
}

void probeLeafBox(uint i, uint id) {
  LEAF_BOXES[i].center_x = mf(id);
  LEAF_BOXES[i].center_y = mf(id + 1u);
  LEAF_BOXES[i].center_z = mf(id + 2u);
  LEAF_BOXES[i].size = mf(id + 3u);
  LEAF_BOXES[i].log_odds = mf(id + 4u);
}

void main() {
  if (invocationIndex() != 0u) return;

  // ScanParams: 100 + field index.
  params.resolution = md(100u);
  params.resolution_factor = md(101u);
  params.max_range = md(102u);
  params.origin_x = mf(103u);
  params.origin_y = mf(104u);
  params.origin_z = mf(105u);
  params.prob_hit_log = mf(106u);
  params.prob_miss_log = mf(107u);
  params.clamp_min_log = mf(108u);
  params.clamp_max_log = mf(109u);
  params.point_count = mu(110u);
  params.hash_capacity = mu(111u);
  params.hash_log2 = mu(112u);
  params.endpoint_capacity = mu(113u);
  params.endpoint_log2 = mu(114u);
  params.rot_u = mf(115u);
  params.rot_x = mf(116u);
  params.rot_y = mf(117u);
  params.rot_z = mf(118u);
  params.active_capacity = mu(119u);
  params.trans_x = mf(120u);
  params.trans_y = mf(121u);
  params.trans_z = mf(122u);
  params.occupancy_log = mf(123u);
  params.changes_log2 = mu(124u);
  params.cell_capacity = mu(125u);
  params.pad0 = mu(126u);

  // ScanCounters: scalars 200 + field index; touched_count 340 + level; walk_count 370 + list,
  // walk_args 380 + 3 * list + component; touched_args 500 + 3 * level + component.
  counters.status = mu(200u);
  counters.brick_entries = mu(201u);
  counters.endpoint_entries = mu(202u);
  counters.active_cells = mu(203u);
  counters.skipped_nonfinite = mu(204u);
  counters.skipped_outside = mu(205u);
  counters.occupied_cells = mu(206u);
  counters.free_cells = mu(207u);
  counters.aborted = mu(208u);
  counters.new_blocks = mu(209u);
  counters.cell_entries = mu(210u);
  counters.query_results = mu(211u);
  counters.leaf_cells = mu(212u);
  counters.no_depth = mu(213u);
  for (uint l = 0u; l < kLevelCount; ++l) {
    counters.touched_count[l] = mu(340u + l);
    counters.touched_args[l].x = mu(500u + 3u * l);
    counters.touched_args[l].y = mu(501u + 3u * l);
    counters.touched_args[l].z = mu(502u + 3u * l);
  }
  for (uint w = 0u; w < 2u; ++w) {
    counters.walk_count[w] = mu(370u + w);
    counters.walk_args[w].x = mu(380u + 3u * w);
    counters.walk_args[w].y = mu(381u + 3u * w);
    counters.walk_args[w].z = mu(382u + 3u * w);
  }
  counters.cell_args.x = mu(390u);
  counters.cell_args.y = mu(391u);
  counters.cell_args.z = mu(392u);
  counters.brick_args.x = mu(393u);
  counters.brick_args.y = mu(394u);
  counters.brick_args.z = mu(395u);
  counters.block_args.x = mu(396u);
  counters.block_args.y = mu(397u);
  counters.block_args.z = mu(398u);
  counters.active_args.x = mu(399u);
  counters.active_args.y = mu(214u);
  counters.active_args.z = mu(215u);
  counters.clear_args.x = mu(216u);
  counters.clear_args.y = mu(217u);
  counters.clear_args.z = mu(218u);

  // PoolState: 600 + field index.
  pool.bump = mu(600u);
  pool.capacity = mu(601u);
  pool.free_count = mu(602u);
  pool.halted = mu(603u);
  pool.root_exists = mu(604u);
  pool.leaf_count = mu(605u);
  pool.live_nodes = mu(606u);
  pool.pad0 = mu(607u);

  // Arrays of structs: element 0 at 700 + 10 * struct, element 1 five further.
  probeNode(0u, 700u);
  probeNode(1u, 705u);
  probeActiveCell(0u, 720u);
  probeActiveCell(1u, 725u);
  probeNewBlock(0u, 730u);
  probeNewBlock(1u, 735u);
  probeLeafBox(0u, 740u);
  probeLeafBox(1u, 750u);

  // Query structs: RayQuery 900 + 10 * element, BoxQuery 920, LookupResult 930 + 5 * element,
  // RayResult 940 + 5 * element, RayState 960 + 10 * element.
  for (uint e = 0u; e < 2u; ++e) {
    uint id = 900u + 10u * e;
    probe_rays[e].max_range = md(id);
    probe_rays[e].origin_x = mf(id + 1u);
    probe_rays[e].origin_y = mf(id + 2u);
    probe_rays[e].origin_z = mf(id + 3u);
    probe_rays[e].direction_x = mf(id + 4u);
    probe_rays[e].direction_y = mf(id + 5u);
    probe_rays[e].direction_z = mf(id + 6u);
    probe_rays[e].ignore_unknown = mu(id + 7u);
    probe_rays[e].pad0 = mu(id + 8u);
    id = 930u + 5u * e;
    probe_lookups[e].state = mu(id);
    probe_lookups[e].log_odds = mf(id + 1u);
    probe_lookups[e].depth = mu(id + 2u);
    probe_lookups[e].pad0 = mu(id + 3u);
    id = 940u + 5u * e;
    probe_ray_results[e].hit = mu(id);
    probe_ray_results[e].end_x = mf(id + 1u);
    probe_ray_results[e].end_y = mf(id + 2u);
    probe_ray_results[e].end_z = mf(id + 3u);
  }
  for (uint e = 0u; e < 2u; ++e) {
    uint id = 960u + 10u * e;
    probe_states[e].t_max_x = md(id);
    probe_states[e].t_max_y = md(id + 1u);
    probe_states[e].t_max_z = md(id + 2u);
    probe_states[e].key_x = mu(id + 3u);
    probe_states[e].key_y = mu(id + 4u);
    probe_states[e].key_z = mu(id + 5u);
    probe_states[e].done = mu(id + 6u);
    probe_states[e].unfinished[0] = mu(id + 7u);
    probe_states[e].unfinished[1] = mu(id + 8u);
  }
  probe_box.min_x = mu(920u);
  probe_box.min_y = mu(921u);
  probe_box.min_z = mu(922u);
  probe_box.max_x = mu(923u);
  probe_box.max_y = mu(924u);
  probe_box.max_z = mu(925u);
  probe_box.occupied_only = mu(926u);
  probe_box.pad0 = mu(927u);

  // WalkState: 1000 + 10 * element.
  for (uint e = 0u; e < 2u; ++e) {
    uint id = 1000u + 10u * e;
    probe_walks[e].t_max_x = md(id);
    probe_walks[e].t_max_y = md(id + 1u);
    probe_walks[e].t_max_z = md(id + 2u);
    probe_walks[e].end_x = mf(id + 3u);
    probe_walks[e].end_y = mf(id + 4u);
    probe_walks[e].end_z = mf(id + 5u);
    probe_walks[e].key_xy = mu(id + 6u);
    probe_walks[e].key_z = mu(id + 7u);
    probe_walks[e].pad0 = mu(id + 8u);
  }

  // Arrays of scalars: element 1.
  POINTS[1] = mf(800u);
  CELL_SET_KEYS[1] = m64(801u);
  CELL_SET_FLAGS[1] = mu(802u);
  FREE_STACK[1] = mu(803u);
  ENDPOINT_KEYS[1] = m64(804u);
  SLOTS[1] = mu(805u);
  CELL_LIST[1] = mu(806u);
  BLOCK_PARENT[1] = mu(807u);
  // DepthCamera at the start of the depth buffer, then its first pixel word: 810 + field index.
  DEPTH_IMAGE.camera.fx = mf(810u);
  DEPTH_IMAGE.camera.fy = mf(811u);
  DEPTH_IMAGE.camera.cx = mf(812u);
  DEPTH_IMAGE.camera.cy = mf(813u);
  DEPTH_IMAGE.camera.depth_scale = mf(814u);
  DEPTH_IMAGE.camera.width = mu(815u);
  DEPTH_IMAGE.camera.height = mu(816u);
  DEPTH_IMAGE.camera.encoding = mu(817u);
  DEPTH_IMAGE.words[0] = mu(818u);

  // The passes' push-constant structs: 1100 + 10 * struct (in gpu_types.h's order) + field.
  probe_no_constants = NoConstants(mu(1100u), mu(1101u), mu(1102u), mu(1103u));
  probe_clear_sets.mode = mu(1110u);
  probe_clear_sets.pad0 = mu(1111u);
  probe_clear_sets.pad1 = mu(1112u);
  probe_clear_sets.pad2 = mu(1113u);
  probe_transform_points.point_count = mu(1120u);
  probe_transform_points.pad0 = mu(1121u);
  probe_transform_points.pad1 = mu(1122u);
  probe_transform_points.pad2 = mu(1123u);
  probe_discretize.point_count = mu(1130u);
  probe_discretize.pad0 = mu(1131u);
  probe_discretize.pad1 = mu(1132u);
  probe_discretize.pad2 = mu(1133u);
  probe_ray_keys.budget = mu(1140u);
  probe_ray_keys.point_count = mu(1141u);
  probe_ray_keys.mode = mu(1142u);
  probe_ray_keys.from_list = mu(1143u);
  probe_unproject.pixel_count = mu(1150u);
  probe_unproject.pad0 = mu(1151u);
  probe_unproject.pad1 = mu(1152u);
  probe_unproject.pad2 = mu(1153u);
  probe_prune.level = mu(1160u);
  probe_prune.pad0 = mu(1161u);
  probe_prune.pad1 = mu(1162u);
  probe_prune.pad2 = mu(1163u);
  probe_leaf_boxes.mode = mu(1170u);
  probe_leaf_boxes.pad0 = mu(1171u);
  probe_leaf_boxes.pad1 = mu(1172u);
  probe_leaf_boxes.pad2 = mu(1173u);
  probe_lookup.point_count = mu(1180u);
  probe_lookup.first_float = mu(1181u);
  probe_lookup.first_result = mu(1182u);
  probe_lookup.pad0 = mu(1183u);
  probe_cast_ray.budget = mu(1190u);
  probe_cast_ray.ray_count = mu(1191u);
  probe_cast_ray.resume = mu(1192u);
  probe_cast_ray.first_state = mu(1193u);
  probe_device_probe.mode = mu(1200u);
  probe_device_probe.case_count = mu(1201u);
  probe_device_probe.loop_iterations = mu(1202u);
  probe_device_probe.pad0 = mu(1203u);

  // Push constants and shared constants, as the shader sees them.
  TOUCHED[0] = pc.budget;
  TOUCHED[1] = pc.point_count;
  TOUCHED[2] = pc.mode;
  TOUCHED[3] = pc.from_list;
  TOUCHED[4] = gl_WorkGroupSize.x;
  TOUCHED[5] = kLevelCount;
  TOUCHED[6] = kTreeDepth;
  TOUCHED[7] = kNoBlock;
}
