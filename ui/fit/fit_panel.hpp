#pragma once
// The co-moving fit panel (issue 8, part 3): fits the selected candidate in a worker (its own JobRunner;
// CoreServices::fitCandidate, paper §3.2 \label{comoving_lsq}) with Cancel, and shows it converge: the cost
// per iteration on a log scale and the residual image (data - model summed along the track), updated at
// most every kLiveIntervalMs through queued calls. When done: data | model | residual on one scale and the
// parameter table with the noise-model and Hessian sigmas, the paper's formulas (eq:sig, cent_snr, vel_snr),
// photons per frame, SNR (detection_snr) and the false-alarm probability (\label{Prob_false}) with the
// search's trial counts. "Accept" stores the fit on the candidate (Observation::setCandidateFit).
#include <QElapsedTimer>
#include <QWidget>
#include <memory>
#include <optional>

#include "core_services.hpp"
#include "observation.hpp"

class QCustomPlot;
class QLabel;
class QPushButton;
class QTableWidget;

namespace st::ui {

class JobRunner;
class StampStrip;

class FitPanel : public QWidget {
  Q_OBJECT
 public:
  /// Minimum time between two live updates of the plots (ms).
  static constexpr int kLiveIntervalMs = 100;

  FitPanel(Observation* observation, const CoreServices* services, QWidget* parent = nullptr);
  ~FitPanel() override;

  [[nodiscard]] QCustomPlot* costPlot() const noexcept { return m_cost; }
  [[nodiscard]] StampStrip* residualView() const noexcept { return m_residual; }
  [[nodiscard]] QTableWidget* parameterTable() const noexcept { return m_table; }
  [[nodiscard]] QPushButton* acceptButton() const noexcept { return m_accept; }
  [[nodiscard]] JobRunner* jobs() const noexcept { return m_jobs; }
  [[nodiscard]] bool running() const;
  /// The last finished fit (null before the first) and the candidate it belongs to.
  [[nodiscard]] const std::shared_ptr<const FitOutcome>& outcome() const noexcept { return m_outcome; }
  [[nodiscard]] int fittedIndex() const noexcept { return m_fittedIndex; }
  /// Iterations plotted so far.
  [[nodiscard]] int costPoints() const;
  [[nodiscard]] QString statusText() const;
  /// The line above the buttons: what Fit would do now (no candidates yet / select one / candidate N
  /// selected, ready to fit / fitting / fit done, Accept stores it / fit stored).
  [[nodiscard]] QString titleText() const;

 public slots:
  /// Fits the selected candidate (does nothing without one, or while a fit runs).
  void fitSelected();
  void cancel();
  /// Stores the last fit on its candidate.
  void accept();

 signals:
  /// A fit ended: ok, cancelled, or failed with a message.
  void fitFinished(bool ok, bool cancelled, const QString& message);
  void accepted(int candidateIndex);

 private:
  struct Live;
  void drainLive();
  void showOutcome(const FitOutcome& outcome);
  void fillTable(const FitOutcome& outcome);
  /// The table of an accepted fit kept on candidate `index` (its FitSummary: no Hessian sigmas, no plots).
  void fillStoredTable(int index, const candidate::FitSummary& fit);
  /// On a new selection: the table of the selected candidate's accepted fit (a reopened session's too), or
  /// of the last fit when it is the selected candidate's.
  void showSelectedFit();
  void resetPlots();
  /// Sets the title line from the observation's state and the last fit (titleText()).
  void updateTitle();
  void rescaleCost();

  Observation* m_obs;
  const CoreServices* m_services;
  JobRunner* m_jobs;
  QLabel* m_title;
  QLabel* m_status;
  QPushButton* m_fit;
  QPushButton* m_cancel;
  QPushButton* m_accept;
  QCustomPlot* m_cost;
  StampStrip* m_residual;
  QTableWidget* m_table;
  std::shared_ptr<Live> m_live;
  std::shared_ptr<const FitOutcome> m_outcome;
  int m_fittedIndex = -1;
  int m_runningIndex = -1;
  double m_cost0 = 0.0;  ///< the fit's first cost: the plot shows its change from there, C / C0 - 1
};

}  // namespace st::ui
