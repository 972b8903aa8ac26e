#include "coupler/text.hpp"

#include <charconv>
#include <cstdio>

namespace coupler {

std::string shortest(double v) {
  char buf[64];
  const auto end = std::to_chars(buf, buf + sizeof(buf), v).ptr;
  return std::string(buf, end);
}

std::string general(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*g", digits, v);
  return buf;
}

}    // namespace coupler
