// A number as messages print it: six significant digits, the stream's default notation.
#pragma once
#include <iomanip>
#include <sstream>
#include <string>

namespace peri {

inline std::string number_text(double v) {
  std::ostringstream s;
  s << std::setprecision(6) << v;
  return s.str();
}

}  // namespace peri
