#include "ui/field_widgets.h"

#include <imgui.h>

#include "renderer/accel/kdtree.h"
#include "renderer/render/render_options.h"

namespace kdt::ui {

namespace {

constexpr double kSliderSpan = 1e4;

bool choice_getter(void* data, int i, const char** out) {
    const auto* choices = static_cast<const std::span<const char* const>*>(data);
    if (i < 0 || size_t(i) >= choices->size()) return false;
    *out = (*choices)[size_t(i)];
    return true;
}

}  // namespace

template <class S>
bool field_widget(const char* group, S& s, const Field<S>& f, std::string* error) {
    const std::string label = std::string(f.name) + "##" + group;
    S edited = s;
    const FieldRef r = f.at(edited);
    bool changed = false;
    const bool slider = f.max - f.min <= kSliderSpan;
    if (auto* b = std::get_if<bool*>(&r)) {
        changed = ImGui::Checkbox(label.c_str(), *b);
    } else if (auto* c = std::get_if<ChoiceRef>(&r)) {
        int v = *c->value;
        auto choices = f.choices;
        if (ImGui::Combo(label.c_str(), &v, choice_getter, &choices, int(choices.size()))) {
            *c->value = uint8_t(v);
            changed = true;
        }
    } else if (auto* i = std::get_if<int*>(&r)) {
        const int lo = int(f.min), hi = int(f.max);
        changed = slider ? ImGui::SliderInt(label.c_str(), *i, lo, hi)
                         : ImGui::InputInt(label.c_str(), *i, 1, 100,
                                           ImGuiInputTextFlags_EnterReturnsTrue);
    } else if (auto* fl = std::get_if<float*>(&r)) {
        const float lo = float(f.min), hi = float(f.max);
        changed = slider ? ImGui::SliderFloat(label.c_str(), *fl, lo, hi, "%.4g")
                         : ImGui::InputFloat(label.c_str(), *fl, 0.0f, 0.0f, "%.4g",
                                             ImGuiInputTextFlags_EnterReturnsTrue);
    } else if (auto* d = std::get_if<double*>(&r)) {
        changed = slider ? ImGui::SliderScalar(label.c_str(), ImGuiDataType_Double, *d, &f.min,
                                               &f.max, "%.4g")
                         : ImGui::InputDouble(label.c_str(), *d, 0.0, 0.0, "%.4g",
                                              ImGuiInputTextFlags_EnterReturnsTrue);
    } else if (auto* u = std::get_if<uint64_t*>(&r)) {
        changed = ImGui::InputScalar(label.c_str(), ImGuiDataType_U64, *u, nullptr, nullptr,
                                     nullptr, ImGuiInputTextFlags_EnterReturnsTrue);
    }
    if (ImGui::IsItemHovered()) {
        ImGui::SetTooltip("%s.%s: %s\n%s", group, f.name, f.help, field_range_text(f).c_str());
    }
    if (!changed) return false;
    if (std::string why = check_field(f, edited); !why.empty()) {
        if (error) *error = std::string(group) + "." + f.name + " " + why;
        return false;
    }
    s = edited;
    return true;
}

template <class S>
bool field_widgets(const char* group, S& s, std::span<const Field<S>> fields, std::string* error) {
    bool changed = false;
    for (const Field<S>& f : fields) changed |= field_widget(group, s, f, error);
    return changed;
}

#define KDT_WIDGETS(S)                                                             \
    template bool field_widget<S>(const char*, S&, const Field<S>&, std::string*); \
    template bool field_widgets<S>(const char*, S&, std::span<const Field<S>>, std::string*);
KDT_WIDGETS(KdTreeParams)
KDT_WIDGETS(TraceParams)
KDT_WIDGETS(FilmParams)
KDT_WIDGETS(StopConditions)
KDT_WIDGETS(SceneOptions)
#undef KDT_WIDGETS

}  // namespace kdt::ui
