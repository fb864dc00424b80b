// Compiled (not run) by ctest: with OCTOVK_WRONG_CONSTANTS, OCTOVK_WRONG_SHADER or
// OCTOVK_MISSING_CONSTANTS defined it must fail to compile with the typed check's diagnostic
// (tests octovk_dispatch_rejects_*, which match it, so that another error does not pass them);
// without them it must compile. See map/passes/recorder.hpp.
#include "map/passes/recorder.hpp"

namespace octovk::passes {

void record(Recorder& r) {
#if defined(OCTOVK_WRONG_CONSTANTS)
  r.dispatch<Shader::kPrune>(1, gpu::LeafBoxesConstants{});  // prune declares PruneConstants
#elif defined(OCTOVK_WRONG_SHADER)
  r.dispatch<Shader::kPrnue>(1, gpu::PruneConstants{});  // no such shader
#elif defined(OCTOVK_MISSING_CONSTANTS)
  r.dispatch<Shader::kPrune>(1);  // prune takes constants: they must be spelled out
#else
  r.dispatch<Shader::kPrune>(1, gpu::PruneConstants{});
  r.dispatch<Shader::kTreeGate>(1);
#endif
}

}  // namespace octovk::passes
