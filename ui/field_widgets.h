// ImGui widgets generated from the range tables of the option structs (renderer/core/fields.h):
// one widget per field, its label, tooltip, limits and choices read from the table, so a new
// field is a new widget with no code here. Depends on core and Dear ImGui.
#pragma once

#include <span>
#include <string>

#include "renderer/core/fields.h"

namespace kdt::ui {

/// Draws the widgets of `fields` for `s` (a slider for a range of at most 10^4, else an input
/// box; a checkbox for a bool; a combo for a choice) and returns whether a value changed. An
/// edit outside the field's range is not applied; its reason goes to *error (named
/// "group.name") and the value stays.
template <class S>
bool field_widgets(const char* group, S& s, std::span<const Field<S>> fields, std::string* error);

/// The widget of one field; the same rules.
template <class S>
bool field_widget(const char* group, S& s, const Field<S>& field, std::string* error);

/// The field of `fields` named `name`, or null.
template <class S>
const Field<S>* find_field(std::span<const Field<S>> fields, const std::string& name) {
    for (const Field<S>& f : fields) {
        if (name == f.name) return &f;
    }
    return nullptr;
}

}  // namespace kdt::ui
