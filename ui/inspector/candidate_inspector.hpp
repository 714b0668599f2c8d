#pragma once
// The candidate inspector (issue 8, part 1): for the selected candidate, computed in a worker
// (candidate::inspectCandidate, st/candidate/inspection.hpp): the stamps at the sky rate and at the candidate's velocity
// side by side on one scale, the segment strip (K = 4 equal-time stacks with their SNRs, flagged ones
// framed in red), the frame-by-frame cutouts along the track as a scrubbable strip with a play/pause movie,
// and the artifact flags of st::vet with their evidence, which are stored on the candidate
// (Observation::setCandidateArtifacts) unless "Store on candidate" is unchecked. "Load known objects…" reads
// a CSV (st::vet::readKnownObjects) and adds the known-object check.
#include <QElapsedTimer>
#include <QFutureWatcher>
#include <QString>
#include <QTimer>
#include <QWidget>
#include <memory>
#include <vector>

#include "st/candidate/inspection.hpp"
#include "core_services.hpp"
#include "observation.hpp"

class QLabel;
class QSlider;
class QToolButton;
class QPushButton;
class QTreeWidget;
class QDoubleSpinBox;
class QCheckBox;
class QGroupBox;

namespace st::ui {

using candidate::Inspection;
using candidate::InspectionInput;

class StampStrip;

class CandidateInspector : public QWidget {
  Q_OBJECT
 public:
  /// Cutouts shown at once in the frame strip (the slider's frame among them).
  static constexpr int kMovieTiles = 5;

  CandidateInspector(Observation* observation, const CoreServices* services, QWidget* parent = nullptr);
  ~CandidateInspector() override;

  /// Reads a known-object CSV in a worker; on success the selected candidate is inspected again. Errors
  /// (naming the file and line) go to the status line and knownObjectsFailed.
  void loadKnownObjects(const QString& path);

  [[nodiscard]] StampStrip* stamps() const noexcept { return m_stamps; }
  [[nodiscard]] StampStrip* segmentStrip() const noexcept { return m_segments; }
  [[nodiscard]] StampStrip* movieView() const noexcept { return m_movie; }
  [[nodiscard]] QSlider* movieSlider() const noexcept { return m_slider; }
  /// The tile of movieView() that shows the slider's frame.
  [[nodiscard]] int movieCurrentTile() const noexcept { return m_movieCurrent; }
  [[nodiscard]] QTreeWidget* flagList() const noexcept { return m_flags; }
  /// The last inspection shown (null before the first), and the candidate it belongs to.
  [[nodiscard]] const std::shared_ptr<const Inspection>& inspection() const noexcept { return m_shown; }
  [[nodiscard]] int inspectedIndex() const noexcept { return m_shownIndex; }
  /// An inspection is running or its result (flags stored on the candidate) is not yet applied: the
  /// watcher's finished signal is queued after the worker stops.
  [[nodiscard]] bool busy() const { return m_pending; }
  [[nodiscard]] std::size_t knownObjectCount() const { return m_known ? m_known->size() : 0; }
  [[nodiscard]] QString statusText() const;
  /// The header: the selected candidate's SNR, motion relative to the stars (in the Search dock's unit) and
  /// position.
  [[nodiscard]] QString titleText() const;
  [[nodiscard]] bool playing() const { return m_playTimer.isActive(); }
  /// Whether every inspection stores its flags on the candidate (Observation::setCandidateArtifacts, which
  /// the session saves; unchanged flags are not stored again). On by default (a setting); off, inspecting
  /// a candidate changes nothing in the session. Turning it on stores the flags shown.
  void setStoreFlags(bool on);
  [[nodiscard]] bool storesFlags() const;

 public slots:
  /// Inspects the selected candidate again (cancels a running inspection).
  void refresh();
  void setPlaying(bool on);

 signals:
  /// An inspection reached the widgets.
  void inspected(int candidateIndex);
  void knownObjectsLoaded(int count);
  void knownObjectsFailed(const QString& message);

 private:
  struct Outcome {
    std::shared_ptr<const Inspection> inspection;
    QString error;
    bool cancelled = false;
    int index = -1;
  };
  QGroupBox* buildFlagBox();
  void connectSignals();
  void start();
  void updateTitle();
  void onFinished();
  void showInspection(const Inspection& in);
  bool storeFlags();
  void showFrame(int k);
  void chooseKnownObjects();

  Observation* m_obs;
  const CoreServices* m_services;
  QLabel* m_title;
  StampStrip* m_stamps;
  StampStrip* m_segments;
  QLabel* m_segmentLabel;
  StampStrip* m_movie;
  QSlider* m_slider;
  QToolButton* m_play;
  QLabel* m_frameLabel;
  QTreeWidget* m_flags;
  QLabel* m_evidence;
  QPushButton* m_loadKnown;
  QDoubleSpinBox* m_radius;
  QCheckBox* m_store;
  QLabel* m_status;
  QTimer m_playTimer;
  QElapsedTimer m_clock;
  int m_movieCurrent = 0;
  QFutureWatcher<Outcome> m_watcher;
  std::shared_ptr<CancelToken> m_cancel;
  bool m_restart = false;
  bool m_pending = false;  ///< started, onFinished not yet run
  std::shared_ptr<const Inspection> m_shown;
  int m_shownIndex = -1;
  std::shared_ptr<const std::vector<vet::KnownObject>> m_known;
  QString m_knownPath;
};

}  // namespace st::ui
