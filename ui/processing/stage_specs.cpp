// The Processing panel's stages from the core's description (session/preprocess_settings.hpp), and back.
#include "core_services.hpp"

namespace st::ui {

std::vector<StageSpec> describedStages() {
  std::vector<StageSpec> out;
  for (const session::PreprocessStageSpec& s : session::preprocessStageSpecs()) {
    StageSpec stage;
    stage.name = s.label;
    stage.key = s.key;
    stage.formerKeys = s.formerKeys;
    stage.help = s.help;
    stage.enabled = s.enabledByDefault;
    stage.optional = s.optional;
    for (const auto& p : s.params)
      stage.params.push_back(
          StageParam{p.key, p.label, p.unit, p.defaultValue, p.minimum, p.maximum, p.decimals, p.help});
    for (const auto& f : s.files)
      stage.files.push_back(StageFiles{f.key, f.label, {}, f.help});
    out.push_back(std::move(stage));
  }
  return out;
}

session::PreprocessSettings preprocessSettings(const std::vector<StageSpec>& stages) {
  session::PreprocessSettings out;
  for (const StageSpec& s : stages) {
    if (s.key.empty()) continue;
    if (s.optional) out.enabled[s.key] = s.enabled;
    for (const StageParam& p : s.params)
      out.values[p.key] = p.value;
  }
  return out;
}

bool stageEnabled(const std::vector<StageSpec>& stages, const std::string& key) {
  for (const StageSpec& s : stages)
    if (s.key == key) return s.enabled;
  return true;
}

}  // namespace st::ui
