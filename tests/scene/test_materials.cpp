// Material presets against the papers' tables.
#include <catch2/catch.hpp>

#include "lblight/scene/material.h"

using namespace lblight;

TEST_CASE("Leaf g derives from fs/bs by Steele2009 eq. (4.3) and matches Table 6.1", "[materials]") {
  const auto leaf = material_preset("leaf");
  REQUIRE(leaf);
  const LeafTable& t = leaf_table_6_1();
  for (int c = 0; c < kChannels; ++c) {
    CHECK(leaf->channel[c].g == Approx(g_from_forward_backward(t.fs[c], t.bs[c])));
    CHECK(leaf->channel[c].g == Approx(t.g_printed[c]).margin(5e-4));  // table prints 3 decimals
    CHECK(leaf->channel[c].sigma_a == t.sigma_a[c]);
    CHECK(leaf->channel[c].sigma_s == t.sigma_s[c]);
  }
  CHECK(leaf->absorbs);
}

TEST_CASE("Presets carry the papers' parameters", "[materials]") {
  const auto cloud = material_preset("cloud");
  REQUIRE(cloud);
  CHECK(cloud->channel[1].g == 0.9);
  CHECK(cloud->channel[1].sigma_a == 0.008);
  CHECK(cloud->channel[1].sigma_s == 0.792);
  CHECK(cloud->channel[1].sigma_s / cloud->channel[1].sigma_t() == Approx(0.99));
  CHECK_FALSE(cloud->absorbs);
  CHECK(cloud->channels_equal());

  const auto rose = material_preset("dogrose");
  REQUIRE(rose);
  CHECK(rose->channel[0].g == -0.231);
  CHECK(rose->channel[2].g == -0.750);
  CHECK(rose->channel[1].sigma_a == 0.091);
  CHECK(rose->absorbs);

  const auto pmma = material_preset("pmma");
  REQUIRE(pmma);
  CHECK(pmma->channel[0].g == 0.80);
  CHECK(pmma->channel[1].g == -0.88);
  CHECK(pmma->channel[2].sigma_s == 0.99);
  CHECK_FALSE(pmma->absorbs);

  const auto bark = material_preset("bark");
  REQUIRE(bark);
  for (int c = 0; c < kChannels; ++c) CHECK(bark->channel[c].g == -1.0);
  CHECK_FALSE(bark->absorbs);
  CHECK_FALSE(material_preset("granite"));
}
