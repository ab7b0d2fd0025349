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

  const auto paper_bark = material_preset("paper-bark");  // [Steele2009] sec. 4.1: leaf sigmas, g = -1
  REQUIRE(paper_bark);
  for (int c = 0; c < kChannels; ++c) {
    CHECK(paper_bark->channel[c].g == -1.0);
    CHECK(paper_bark->channel[c].sigma_s == material_preset("leaf")->channel[c].sigma_s);
  }
  CHECK_FALSE(paper_bark->absorbs);
  CHECK_FALSE(material_preset("granite"));
}

TEST_CASE("Bark is opaque, brown, diffusely reflecting wood (docs/model.md, Wood)", "[scene][materials]") {
  const auto bark = material_preset("bark");
  REQUIRE(bark);
  const double albedo[3] = {0.25, 0.17, 0.11};
  for (int c = 0; c < kChannels; ++c) {
    CHECK(bark->channel[c].sigma_t() == Approx(4.0));
    CHECK(bark->channel[c].sigma_s / bark->channel[c].sigma_t() == Approx(albedo[c]));
    CHECK(bark->channel[c].g == Approx(-4.0 / 9.0));  // a diffuse (Lambertian) sphere's phase function
  }
  CHECK(albedo[0] > albedo[1]);  // brown: red reflected most
  CHECK(bark->absorbs);
  // the default wood follows the LB model: physical bark, or the papers' wood behind "paper"
  const Material leaf = *material_preset("leaf");
  CHECK(default_wood(leaf, true).name == "bark");
  const Material paper = default_wood(leaf, false);
  for (int c = 0; c < kChannels; ++c) {
    CHECK(paper.channel[c].g == -1.0);
    CHECK(paper.channel[c].sigma_a == leaf.channel[c].sigma_a);
  }
  CHECK_FALSE(paper.absorbs);
}
