#pragma once
// Scene config files (TOML). Only what a scene needs is written; everything
// else takes the defaults of scene.hpp. Unknown keys and bad values are
// UserErrors that name the key (with its table path) and what is allowed.
#include <string>
#include <string_view>

#include "mpm/scene.hpp"

namespace mpm {

/// Reads and validates a scene file. Throws UserError.
Scene load_scene(const std::string& path);
/// Same, from text; `source` names it in messages.
Scene parse_scene(std::string_view toml_text, const std::string& source = "<string>");
/// Reference of every key, its meaning, unit and default, for `mpm_solver --help`.
std::string config_reference();

}  // namespace mpm
