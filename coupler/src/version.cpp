#include "coupler/version.hpp"

namespace coupler {
const char* release_version() { return HYBRID_VERSION; }
}  // namespace coupler
