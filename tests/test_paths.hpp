// Where the tests find their data and tools: the paths the build compiles in
// (tests/CMakeLists.txt), each overridable by the environment variable of the same name. A bundle
// (scripts/bundle.sh) is run from another folder on a machine without this build or Debian's
// packages; its run.sh points the tests at the bundle's own copies this way. Unset (or empty)
// variables keep the compiled path.
#pragma once

#include <cstdlib>
#include <string>

namespace octovk::test {

inline std::string configuredPath(const char* name, const char* compiled) {
  const char* value = std::getenv(name);
  return value && *value ? std::string(value) : std::string(compiled);
}

}  // namespace octovk::test

/// The path of compile definition NAME (OCTOVK_OCTOMAP_DATA_DIR, OCTOVK_SHARED_DATA_DIR,
/// OCTOVK_GRAPH2TREE, OCTOVK_LOG2GRAPH, OCTOVK_CLI, OCTOVK_TEST_TMP, OCTOVK_SOURCE_DIR), or $NAME
/// when set, as a
/// std::string. (#NAME is the macro's name: a stringized argument is not expanded.)
#define OCTOVK_PATH(NAME) ::octovk::test::configuredPath(#NAME, NAME)
