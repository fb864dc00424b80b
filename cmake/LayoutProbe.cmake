# Writes the layout probe's two halves from the structs that cross the host/device line, as the
# headers declare them (include/octovk/device_types.h, then src/gpu/gpu_types.h): each struct and
# each field is declared once, there, and both the probe's GLSL (every field written with a
# marker) and the host's table (where each marker must land: offsetof) are read off it. The size
# and offset each header's comments state ("// 4B (12)", "... 20 B.") become static_asserts, and
# the stated fields must tile the struct: padding is a named field.
cmake_minimum_required(VERSION 3.25)  # script mode
# Run as a script: cmake -DHEADERS="a.h;b.h" -DGLSL=fields.glsl -DCPP=table.cpp -P LayoutProbe.cmake

# Where the probe writes each struct: every struct twice in its own region of the kBindTouched
# buffer (from byte kRegionsAt, kRegionBytes each), by device address; and the views the passes
# reach it by (bindings.glsl): struct or scalar type | GLSL expression of element @ | binding |
# byte offset of element 0 in the binding's buffer (C++) | elements written.
set(kRegionsAt 256)
set(kRegionBytes 2048)
set(VIEWS
  "ScanParams|params|kBindParams|0|1"
  "ScanCounters|counters|kBindCounters|0|1"
  "PoolState|pool|kBindPool|0|1"
  "Node|NODES[@]|kBindNodes|0|2"
  "ActiveCell|CELLS[@]|kBindActive|0|2"
  "NewBlock|PREFIX_BLOCKS[@]|kBindNewBlocks|0|2"
  "LeafBox|LEAF_BOXES[@]|kBindLeafBoxes|0|2"
  "WalkState|WALKS[@]|kBindWalks|0|2"
  "DepthCamera|DEPTH_IMAGE.camera|kBindDepth|0|1"
  "uint|DEPTH_IMAGE.words[@]|kBindDepth|sizeof(DepthCamera)|2"
  "ChangeHeader|CHANGE_TABLE.header|kBindChanges|0|1"
  "ChangeSlot|CHANGE_TABLE.slot[@]|kBindChanges|sizeof(ChangeHeader)|2"
  "float|POINTS[@]|kBindPoints|0|2"
  "uint64_t|CELL_SET_KEYS[@]|kBindCellSetKeys|0|2"
  "uint|CELL_SET_FLAGS[@]|kBindCellSetFlags|0|2"
  "uint|BLOCK_PARENT[@]|kBindBlockParents|0|2"
  "uint|FREE_STACK[@]|kBindFreeStack|0|2"
  "uint64_t|ENDPOINT_KEYS[@]|kBindEndpointKeys|0|2"
  "uint|SLOTS[@]|kBindSlots|0|2"
  "uint|CELL_LIST[@]|kBindCellList|0|2")

set(scalar_kinds "uint=kUint;float=kFloat;double=kDouble;uint64_t=kUint64")
set(scalar_markers "uint=mu;float=mf;double=md;uint64_t=m64")
function(scalar_info type kinds result)
  foreach(pair IN LISTS ${kinds})
    if(pair MATCHES "^${type}=(.*)$")
      set(${result} "${CMAKE_MATCH_1}" PARENT_SCOPE)
      return()
    endif()
  endforeach()
  set(${result} "" PARENT_SCOPE)
endfunction()

# ---- reading the headers ----
set(header_names "")
set(structs "")
set(asserts "")
foreach(header IN LISTS HEADERS)
  get_filename_component(header_name "${header}" NAME)
  list(APPEND header_names "${header_name}")
  file(READ "${header}" text)
  # One list element per line, with the characters lists treat specially kept out of the way.
  string(REPLACE ";" "<semicolon>" text "${text}")
  string(REPLACE "[" "<open>" text "${text}")
  string(REPLACE "]" "<close>" text "${text}")
  string(REPLACE "\n" ";" lines "${text}")
  set(conditions "")  # the #if stack: "cpp" inside #ifdef __cplusplus, else "-"
  set(in_struct "")
  set(stated_size "")
  set(number 0)
  foreach(line IN LISTS lines)
    math(EXPR number "${number} + 1")
    string(REPLACE "<semicolon>" ";" line "${line}")
    string(REPLACE "<open>" "[" line "${line}")
    string(REPLACE "<close>" "]" line "${line}")
    set(where "${header_name}:${number}")
    if(line MATCHES "^#ifdef __cplusplus")
      list(APPEND conditions cpp)
    elseif(line MATCHES "^#if")
      list(APPEND conditions -)
    elseif(line MATCHES "^#else")
      list(POP_BACK conditions)
      list(APPEND conditions -)
    elseif(line MATCHES "^#endif")
      list(POP_BACK conditions)
    elseif(line MATCHES "^OCTOVK_[A-Z_]*CONST uint (k[A-Za-z0-9]+) = ([0-9]+)u;")
      set(constant_${CMAKE_MATCH_1} "${CMAKE_MATCH_2}")
    elseif(in_struct)
      if(line MATCHES "^};")
        if(NOT skip_struct)
          if(NOT end EQUAL size_${in_struct})
            message(FATAL_ERROR "${where}: the fields of ${in_struct} end at byte ${end}, but it is "
                                "stated to be ${size_${in_struct}} B: name the padding")
          endif()
          list(APPEND structs "${in_struct}")
          set(fields_${in_struct} "${fields}")
        endif()
        set(in_struct "")
      elseif(line MATCHES "^ *(//.*)?$")
      elseif(line MATCHES "^  ([A-Za-z0-9_]+) ([a-z0-9_]+)(\\[([A-Za-z0-9]+)\\])?; +// ([0-9]+)B \\(([0-9]+)\\)")
        set(type "${CMAKE_MATCH_1}")
        set(field "${CMAKE_MATCH_2}")
        set(count "${CMAKE_MATCH_4}")
        set(bytes "${CMAKE_MATCH_5}")
        set(offset "${CMAKE_MATCH_6}")
        if(count MATCHES "^k")
          if(NOT DEFINED constant_${count})
            message(FATAL_ERROR "${where}: ${in_struct}::${field}'s length ${count} is no "
                                "constant defined above it")
          endif()
          set(count "${constant_${count}}")
        endif()
        if(NOT offset EQUAL end)
          message(FATAL_ERROR "${where}: ${in_struct}::${field} is stated at byte ${offset}, but "
                              "the field before it ends at ${end}: name the padding")
        endif()
        math(EXPR end "${end} + ${bytes}")
        list(APPEND fields "${type}|${field}|${count}")
        string(APPEND asserts
          "static_assert(offsetof(${in_struct}, ${field}) == ${offset} && "
          "sizeof(${in_struct}::${field}) == ${bytes},\n"
          "              \"${header_name}: ${in_struct}::${field} is not the ${bytes}B (${offset}) "
          "its comment states\");\n")
      else()
        message(FATAL_ERROR "${where}: not a field as the layout probe reads them "
                            "(\"  type name[length]; // NB (offset) ...\"):\n${line}")
      endif()
    elseif(line MATCHES "^//.* ([0-9]+) B\\.")
      set(stated_size "${CMAKE_MATCH_1}")
    elseif(line MATCHES "^struct ([A-Za-z0-9_]+) {$")
      set(in_struct "${CMAKE_MATCH_1}")
      set(fields "")
      set(end 0)
      set(skip_struct FALSE)
      if("cpp" IN_LIST conditions)
        set(skip_struct TRUE)  # the host's alone (PassConstants): no GLSL twin to probe
      elseif(stated_size STREQUAL "")
        message(FATAL_ERROR "${where}: the comment above struct ${in_struct} states no size "
                            "(\"... N B.\")")
      else()
        set(size_${in_struct} "${stated_size}")
        string(APPEND asserts
          "static_assert(std::is_standard_layout_v<${in_struct}> && "
          "std::is_trivially_copyable_v<${in_struct}>);\n"
          "static_assert(sizeof(${in_struct}) == ${stated_size}, \"${header_name}: ${in_struct} is "
          "not the ${stated_size} B its comment states\");\n")
        math(EXPR twice "2 * ${stated_size}")
        if(twice GREATER kRegionBytes)
          message(FATAL_ERROR "${where}: two ${in_struct}s do not fit the probe's region of "
                              "${kRegionBytes} bytes: raise kRegionBytes in cmake/LayoutProbe.cmake")
        endif()
      endif()
      set(stated_size "")
    endif()
  endforeach()
endforeach()

# ---- the fields, in marker order ----
# Appends every scalar of a `type` at GLSL `glsl` and C++ byte offset `at` (an expression) to the
# GLSL writes and the host's table, where `name` names it for the test's messages.
set_property(GLOBAL PROPERTY probe_glsl "")
set_property(GLOBAL PROPERTY probe_rows "")
set_property(GLOBAL PROPERTY probe_id 0)
function(probe type glsl name at binding)
  if(DEFINED fields_${type})
    foreach(entry IN LISTS fields_${type})
      string(REPLACE "|" ";" entry "${entry}")
      list(GET entry 0 ftype)
      list(GET entry 1 field)
      list(GET entry 2 count)
      set(field_at "${at} + offsetof(${type}, ${field})")
      if(count STREQUAL "")
        probe("${ftype}" "${glsl}.${field}" "${name}.${field}" "${field_at}" "${binding}")
      else()
        math(EXPR last "${count} - 1")
        foreach(i RANGE ${last})
          probe("${ftype}" "${glsl}.${field}[${i}]" "${name}.${field}[${i}]"
                "${field_at} + ${i} * sizeof(${ftype})" "${binding}")
        endforeach()
      endif()
    endforeach()
    return()
  endif()
  scalar_info("${type}" scalar_kinds kind)
  scalar_info("${type}" scalar_markers marker)
  if(kind STREQUAL "")
    message(FATAL_ERROR "layout probe: ${glsl} has the type ${type}, neither a probed struct nor "
                        "uint, float, double or uint64_t")
  endif()
  get_property(id GLOBAL PROPERTY probe_id)
  set_property(GLOBAL APPEND_STRING PROPERTY probe_glsl "  ${glsl} = ${marker}(${id}u);\n")
  set_property(GLOBAL APPEND_STRING PROPERTY probe_rows
               "    {\"${name}\", ${binding}, ${at}, Kind::${kind}},\n")
  math(EXPR id "${id} + 1")
  set_property(GLOBAL PROPERTY probe_id ${id})
endfunction()

set(spans "")
set(sizes "")
foreach(view IN LISTS VIEWS)
  string(REPLACE "|" ";" view "${view}")
  list(GET view 0 type)
  list(GET view 1 glsl)
  list(GET view 2 binding)
  list(GET view 3 first)
  list(GET view 4 count)
  if(NOT DEFINED fields_${type} AND NOT type MATCHES "^(uint|float|double|uint64_t)$")
    message(FATAL_ERROR "layout probe: the view ${glsl} holds ${type}, no struct of the headers")
  endif()
  set_property(GLOBAL APPEND_STRING PROPERTY probe_glsl "  // ${type} at ${glsl}\n")
  math(EXPR last "${count} - 1")
  foreach(e RANGE ${last})
    string(REPLACE "@" "${e}" element "${glsl}")
    probe("${type}" "${element}" "${element}" "${first} + ${e} * sizeof(${type})" "${binding}")
  endforeach()
  string(REPLACE "@" "*" shown "${glsl}")
  string(APPEND spans "    {\"${shown}\", ${binding}, ${first}, ${count} * sizeof(${type})},\n")
endforeach()

set(references "")
set(region 0)
foreach(struct IN LISTS structs)
  math(EXPR at "${kRegionsAt} + ${region} * ${kRegionBytes}")
  string(APPEND references "layout(buffer_reference, std430, buffer_reference_align = 16) buffer "
                           "ProbeRegion${struct} { ${struct} v[]; };\n")
  set_property(GLOBAL APPEND_STRING PROPERTY probe_glsl
    "  // ${struct}, twice, at byte ${at} of kBindTouched\n  ProbeRegion${struct} r${region} = \
ProbeRegion${struct}(buffer_address[kBindTouched] + ${at}ul);\n")
  foreach(e 0 1)
    probe("${struct}" "r${region}.v[${e}]" "region ${region}: ${struct}[${e}]"
          "${at} + ${e} * sizeof(${struct})" kBindTouched)
  endforeach()
  string(APPEND spans "    {\"region ${region}: ${struct}[0..1]\", kBindTouched, ${at}, "
                      "2 * sizeof(${struct})},\n")
  string(APPEND sizes "    {\"${struct}\", ${size_${struct}}, sizeof(${struct})},\n")
  math(EXPR region "${region} + 1")
endforeach()

# ---- the outputs ----
get_property(writes GLOBAL PROPERTY probe_glsl)
get_property(rows GLOBAL PROPERTY probe_rows)
get_property(field_count GLOBAL PROPERTY probe_id)
list(JOIN header_names " and " sources)
set(glsl "// Generated by cmake/LayoutProbe.cmake from ${sources}; do not edit.
// Included by shaders/layout_probe.comp, which defines the markers mu, mf, md and m64.
const uint kProbedFields = ${field_count}u;
${references}
void probeEveryField() {
${writes}}
")
set(cpp "// Generated by cmake/LayoutProbe.cmake from ${sources}; do not edit.
#include <cstddef>
#include <type_traits>

#include \"gpu/layout_probe_table.hpp\"

namespace octovk::gpu::layout {

${asserts}
std::span<const ProbedField> probedFields() {
  static const ProbedField fields[] = {
${rows}  };
  return fields;
}

std::span<const ProbedSpan> probedSpans() {
  static const ProbedSpan spans[] = {
${spans}  };
  return spans;
}

std::span<const StatedSize> statedSizes() {
  static const StatedSize sizes[] = {
${sizes}  };
  return sizes;
}

}  // namespace octovk::gpu::layout
")
foreach(out IN ITEMS GLSL CPP)
  string(TOLOWER "${out}" var)
  file(WRITE "${${out}}.tmp" "${${var}}")
  file(COPY_FILE "${${out}}.tmp" "${${out}}" ONLY_IF_DIFFERENT)
  file(REMOVE "${${out}}.tmp")
endforeach()
