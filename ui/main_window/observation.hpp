#pragma once
// The state of one analysis in the GUI: the raw cube, what pre-processing made, the search grid and result,
// the current velocity, the selected candidate and each candidate's vetting state (label, note, accepted fit,
// artifact flags: st::session::CandidateState, the same record the session file keeps). Panels read it and
// listen to its signals; only the GUI thread changes it (results arrive through JobRunner's apply closures).
#include <QObject>
#include <QString>
#include <memory>
#include <optional>

#include "core_services.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/plate_solve_stage.hpp"
#include "st/search/types.hpp"
#include "st/session/session.hpp"
#include "velocity_units.hpp"

namespace st::ui {

class Observation : public QObject {
  Q_OBJECT
 public:
  explicit Observation(QObject* parent = nullptr) : QObject(parent) {}

  [[nodiscard]] const std::shared_ptr<const FrameCube>& raw() const noexcept { return m_raw; }
  [[nodiscard]] const std::shared_ptr<const PreparedView>& prepared() const noexcept { return m_prepared; }
  [[nodiscard]] const std::shared_ptr<const search::SearchResult>& result() const noexcept {
    return m_result;
  }
  [[nodiscard]] const search::VelocityGrid& grid() const noexcept { return m_grid; }
  [[nodiscard]] Velocity velocity() const noexcept { return m_velocity; }
  [[nodiscard]] search::StackMode stackMode() const noexcept { return m_mode; }
  [[nodiscard]] std::optional<int> selected() const noexcept { return m_selected; }
  [[nodiscard]] VelocityUnit unit() const noexcept { return m_unit; }
  [[nodiscard]] const QString& label() const noexcept { return m_label; }
  /// Plate scale of the raw cube (arcsec/px), when known.
  [[nodiscard]] std::optional<double> plateScale() const {
    return m_raw ? m_raw->plateScaleArcsecPerPx : std::nullopt;
  }
  /// Motion of the stars (px/s): from pre-processing, else zero.
  [[nodiscard]] Velocity skyRate() const {
    return m_prepared && m_prepared->filtered ? m_prepared->filtered->skyRate : Velocity{};
  }
  /// The selected candidate, if any.
  [[nodiscard]] const search::Candidate* selectedCandidate() const {
    if (!m_result || !m_selected || *m_selected < 0 ||
        *m_selected >= static_cast<int>(m_result->candidates.size()))
      return nullptr;
    return &m_result->candidates[static_cast<std::size_t>(*m_selected)];
  }

  /// Vetting state of every candidate of result(), in the same order (empty without a result). The
  /// `candidate` JSON member is left for the session writer to fill; the GUI keeps search::Candidate.
  [[nodiscard]] const std::vector<session::CandidateState>& candidateStates() const noexcept {
    return m_states;
  }
  /// The state of candidate `index`, or null when out of range.
  [[nodiscard]] const session::CandidateState* candidateState(int index) const {
    return index >= 0 && index < static_cast<int>(m_states.size())
               ? &m_states[static_cast<std::size_t>(index)]
               : nullptr;
  }

  /// Vetting: the label (a reason only with Label::Artifact, else it is cleared).
  void setCandidateLabel(int index, session::Label label,
                         session::ArtifactReason reason = session::ArtifactReason::None) {
    if (auto* s = mutableState(index)) {
      s->label = label;
      s->reason = label == session::Label::Artifact ? reason : session::ArtifactReason::None;
      emit candidateStateChanged(index);
    }
  }
  void setCandidateNote(int index, std::string note) {
    if (auto* s = mutableState(index)) {
      s->note = std::move(note);
      emit candidateStateChanged(index);
    }
  }
  /// An accepted co-moving fit (candidate::fitCandidate).
  void setCandidateFit(int index, std::optional<candidate::FitSummary> fit) {
    if (auto* s = mutableState(index)) {
      s->fit = std::move(fit);
      emit candidateStateChanged(index);
    }
  }
  /// Artifact flags (st::vet checks and the known-object check).
  void setCandidateArtifacts(int index, std::vector<vet::ArtifactFlag> flags) {
    if (auto* s = mutableState(index)) {
      s->artifacts = std::move(flags);
      emit candidateStateChanged(index);
    }
  }

  /// A WCS found for frames that had none (plate solving, main_window_plate_solve.cpp): attached to the loaded
  /// cube (its wcs, plate scale and header WCS cards, so a later pre-processing carries it as a header WCS)
  /// and to the pre-processed cubes, the one in-place change of the shared cubes. GUI thread only, while no
  /// job runs (the plate-solve job's apply closure): wcs and header are read on the GUI thread and by jobs,
  /// never by the live-stack workers, which read pixels only. Emits wcsChanged.
  void attachWcs(std::shared_ptr<const Wcs> wcs, double plateScaleArcsecPerPx) {
    if (!m_raw || !wcs) return;
    // See above: the documented exception to "const once shared".
    pipeline::attachHeaderWcs(const_cast<FrameCube&>(*m_raw), wcs, plateScaleArcsecPerPx);
    const auto attach = [&](const FrameCube& cube) {
      auto& c = const_cast<FrameCube&>(cube);
      c.wcs = wcs;
      c.plateScaleArcsecPerPx = plateScaleArcsecPerPx;
    };
    if (m_prepared && m_prepared->filtered) attach(m_prepared->filtered->frames);
    if (m_prepared && m_prepared->unfiltered) attach(m_prepared->unfiltered->frames);
    m_solvedWcs = SolvedWcs{std::move(wcs), plateScaleArcsecPerPx};
    emit wcsChanged();
  }
  /// The WCS attached by attachWcs() to this observation's frames, which have none of their own: saved in the
  /// session and attached again when it is reopened. Empty for frames with a header WCS.
  struct SolvedWcs {
    std::shared_ptr<const Wcs> wcs;
    double plateScaleArcsecPerPx = 0.0;
  };
  [[nodiscard]] const std::optional<SolvedWcs>& solvedWcs() const { return m_solvedWcs; }

  /// A new observation: drops everything derived from the previous one.
  void setRaw(std::shared_ptr<const FrameCube> raw, const QString& label) {
    m_raw = std::move(raw);
    m_label = label;
    m_solvedWcs.reset();
    m_prepared.reset();
    m_result.reset();
    m_states.clear();
    m_selected.reset();
    emit rawChanged();
    emit preparedChanged();
    emit resultChanged();
  }
  void setPrepared(std::shared_ptr<const PreparedView> prepared) {
    m_prepared = std::move(prepared);
    m_result.reset();
    m_states.clear();
    m_selected.reset();
    emit preparedChanged();
    emit resultChanged();
  }
  /// A new search result; every candidate starts unvetted unless `states` (one per candidate, e.g. from a
  /// session file) is given. A `states` of the wrong length is ignored.
  void setResult(std::shared_ptr<const search::SearchResult> result,
                 std::vector<session::CandidateState> states = {}) {
    m_result = std::move(result);
    const std::size_t n = m_result ? m_result->candidates.size() : 0;
    m_states = states.size() == n ? std::move(states) : std::vector<session::CandidateState>(n);
    m_selected.reset();
    if (m_result) setGrid(m_result->grid);
    emit resultChanged();
  }
  void setGrid(const search::VelocityGrid& grid) {
    m_grid = grid;
    emit gridChanged();
  }
  void setVelocity(Velocity v) {
    if (v == m_velocity) return;
    m_velocity = v;
    emit velocityChanged(v);
  }
  void setStackMode(search::StackMode mode) {
    if (mode == m_mode) return;
    m_mode = mode;
    emit stackModeChanged();
  }
  void setSelected(std::optional<int> index) {
    m_selected = index;
    emit selectionChanged();
  }
  void setUnit(VelocityUnit unit) {
    m_unit = unit;
    emit unitChanged();
  }
  /// Which candidates the candidates table's filters (SNR, false alarms, flags, label) let through; the
  /// image and velocity-map markers show those only. A candidate beyond the vector is shown.
  void setCandidatesShown(std::vector<bool> shown) {
    if (shown == m_shown) return;
    m_shown = std::move(shown);
    emit candidatesShownChanged();
  }
  [[nodiscard]] bool candidateShown(int index) const noexcept {
    return index < 0 || index >= static_cast<int>(m_shown.size()) || m_shown[static_cast<std::size_t>(index)];
  }

 signals:
  void rawChanged();
  /// The loaded frames got a WCS (attachWcs).
  void wcsChanged();
  void preparedChanged();
  void resultChanged();
  void gridChanged();
  void velocityChanged(st::Velocity v);
  void stackModeChanged();
  void selectionChanged();
  void unitChanged();
  /// A candidate's label, note, fit or artifact flags changed (the session autosaves on it).
  void candidateStateChanged(int index);
  /// The table's filters changed which candidates are shown (setCandidatesShown).
  void candidatesShownChanged();

 private:
  std::shared_ptr<const FrameCube> m_raw;
  std::optional<SolvedWcs> m_solvedWcs;
  std::shared_ptr<const PreparedView> m_prepared;
  session::CandidateState* mutableState(int index) {
    return index >= 0 && index < static_cast<int>(m_states.size())
               ? &m_states[static_cast<std::size_t>(index)]
               : nullptr;
  }

  std::shared_ptr<const search::SearchResult> m_result;
  std::vector<session::CandidateState> m_states;
  std::vector<bool> m_shown;
  search::VelocityGrid m_grid;
  Velocity m_velocity;
  search::StackMode m_mode = search::StackMode::Ipsa;
  std::optional<int> m_selected;
  VelocityUnit m_unit = VelocityUnit::PxPerS;
  QString m_label;
};

}  // namespace st::ui
