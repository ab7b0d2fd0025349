// The scene file's field tables: for every JSON object of a scene (docs/scene-format.md), its
// fields with type, range, default and the "allowed" text errors quote. The parser takes its
// allowed keys, number ranges and defaults from here, and `lblight schema` generates the JSON
// Schema from the same tables, so the two cannot drift apart.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/scene/json_reader.h"

namespace lblight {

enum class FieldKind { Number, Integer, Boolean, String, Custom };

struct FieldSpec {
  std::string key;
  FieldKind kind = FieldKind::Custom;
  bool required = false;
  double lo = 0, hi = 0;               // Number, Integer: inclusive range
  nlohmann::json fallback;             // the parser's default (null: none); the schema shows it when allowed
  std::string allowed;                 // what errors say is allowed; the schema's description
  std::vector<std::string> choices;    // String: the values allowed (empty: any)
  nlohmann::json schema;               // Custom: the value's JSON Schema ("$ref": "#/$defs/<id>" for objects)
};

struct ObjectSpec {
  std::string id, description;
  std::vector<FieldSpec> fields;
  const FieldSpec& field(const std::string& key) const;  // std::logic_error for a key not in the table
};

// The table of one object ("scene", "model", "density.procedural", "solver", ...).
const ObjectSpec& scene_object(const std::string& id);
const std::vector<ObjectSpec>& scene_objects();

// Reads through the table: unknown keys refused with the table's list, numbers and integers
// checked against its range (with its allowed text), defaults from it.
void check_fields(const JsonReader& r, const ObjectSpec& object);
double number_field(const JsonReader& r, const ObjectSpec& object, const std::string& key);
long long integer_field(const JsonReader& r, const ObjectSpec& object, const std::string& key);
bool boolean_field(const JsonReader& r, const ObjectSpec& object, const std::string& key);
std::string string_field(const JsonReader& r, const ObjectSpec& object, const std::string& key);

// The scene file's JSON Schema (draft 2020-12), for `lblight schema` and editors.
nlohmann::json scene_json_schema();

}  // namespace lblight
