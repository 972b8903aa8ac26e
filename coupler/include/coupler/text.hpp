#pragma once
// Numbers in the coupler's messages, written as LAMMPS's fmt writes them, so that a message
// moved from a host's fix into the coupler reads the same.

#include <string>

namespace coupler {

/// The shortest text that reads back as v (fmt's "{}").
std::string shortest(double v);

/// printf's "%.<digits>g" (fmt's "{:.<digits>g}").
std::string general(double v, int digits);

}    // namespace coupler
