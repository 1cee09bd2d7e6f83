#include "tests/ui/viewer_gui.h"

#include <imgui.h>
#include <imgui_impl_opengl3.h>

#include "ui/gl.h"

namespace kdt::test {

ui::ViewerOptions small_viewer_options(int width, int height) {
    ui::ViewerOptions vo;
    vo.options.scene.width = width;
    vo.options.scene.height = height;
    vo.options.tree.threads = 1;
    vo.options.trace.threads = 1;
    return vo;
}

GuiViewer::GuiViewer(const ui::ViewerOptions& options, int width, int height) : gl_(width, height) {
    if (!gl_.ok()) return;
    viewer_.emplace(options);
    viewer_->finish_loading();
    gui_.emplace(*viewer_, width, height);
}

ViewerGui::ViewerGui(ui::Viewer& viewer, int width, int height)
    : v_(viewer), width_(width), height_(height) {
    ImGui::CreateContext();
    ImGuiIO& io = ImGui::GetIO();
    io.IniFilename = nullptr;
    io.DisplaySize = ImVec2(float(width), float(height));
    io.DeltaTime = 1.0f / 60.0f;
    ok_ = ImGui_ImplOpenGL3_Init("#version 330 core");
    if (!ok_) return;
    v_.display_.init();
    v_.image_x_ = 0;
    v_.image_y_ = 0;
    v_.image_w_ = 640;
    v_.image_h_ = 480;
}

ViewerGui::~ViewerGui() {
    if (ok_) ImGui_ImplOpenGL3_Shutdown();
    ImGui::DestroyContext();
}

bool ViewerGui::frame(bool file_panel) {
    ImGui_ImplOpenGL3_NewFrame();
    ImGui::NewFrame();
    v_.poll_rebuild();
    const bool running = v_.script_step();
    v_.update_image();
    v_.draw_panels();
    if (file_panel) v_.draw_file_panel();
    ImGui::Render();
    glViewport(0, 0, width_, height_);
    glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    v_.draw_image(height_);
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    glFinish();
    return running;
}

}  // namespace kdt::test
