// summary.json escapes every string it holds, whatever names reach it: derived constants keyed by
// body name, quasi-static stage names, memory phases; and names its memory figures for what they
// count.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "peri/stages/simulation.hpp"

namespace {

using ::testing::HasSubstr;
using ::testing::Not;

TEST(SummaryJson, EscapesEveryString) {
  peri::RunSummary s;
  s.derived = {{"sheet\"1.horizon", 0.5}, {"a\\b\tc\nd.nodes", 2}, {"plain.micromodulus", 3}};
  s.quasistatic.push_back({"pre\"load\n", peri::QuasiStaticStats{}});
  s.quasistatic_work_error.push_back(0.25);
  s.memory.push_back({"set\\up", 1, 1});
  const std::string j = s.to_json();
  EXPECT_THAT(j, HasSubstr("\"derived\": {\"sheet\\\"1.horizon\": 0.5, \"a\\\\b\\u0009c\\u000ad.nodes\": 2, "
                           "\"plain.micromodulus\": 3}"));
  EXPECT_THAT(j, HasSubstr("{\"stage\": \"pre\\\"load\\u000a\", \"increments\": 0"));
  EXPECT_THAT(j, HasSubstr("{\"phase\": \"set\\\\up\", \"peak_bytes\": 1"));
  // No raw tab, and raw newlines only between members (each line starts a member or closes).
  EXPECT_THAT(j, Not(HasSubstr("\t")));
  std::size_t lines = 0;
  for (std::size_t at = 0; (at = j.find('\n', at)) != std::string::npos; ++at) {
    ++lines;
    if (at + 1 < j.size()) EXPECT_TRUE(j.compare(at + 1, 3, "  \"") == 0 || j[at + 1] == '}') << j.substr(at, 20);
  }
  EXPECT_GT(lines, 20u);
}

// Memory under honest names: the bond arrays per bond (bytes_per_bond, bond_array_bytes_per_bond)
// beside the processes' peak over the phases per ordered bond.
TEST(SummaryJson, NamesBothMemoryFigures) {
  peri::RunSummary s;
  s.ordered_bonds = 100;
  s.bytes_per_bond = 5.25;
  s.memory = {{"nodes", 1000, 900}, {"domain", 3000, 2500}, {"end", 2000, 2000}};
  EXPECT_EQ(s.peak_bytes_per_bond(), 30.0);
  const std::string j = s.to_json();
  EXPECT_THAT(j, HasSubstr("\"bytes_per_bond\": 5.25,\n  \"bond_array_bytes_per_bond\": 5.25,\n  "
                           "\"peak_bytes_per_bond\": 30,"));
}

}  // namespace
