#pragma once
// The memory budget of the GUI and cubes larger than it (issue 20 item 4), beside MainWindow (driving it
// through its public API). Run > Memory limit… sets the budget (QSettings "memory/limit", the CLI's
// --memory-limit syntax: 8G, 500M; empty = 70% of the available memory, st::resolveMemoryBudget); the status
// bar shows it. Opening inputs estimates from their headers what the GUI needs to hold them
// (pipeline::estimateOpenPeak); a pre-processed cube (synthtrack-cli preprocess) that does not fit is opened
// OUT OF CORE (pipeline::openOutOfCore): the view shows the mean of all frames, summed in strips of rows read
// with CFITSIO's subset reader; a banner says so; Search runs through pipeline::searchOutOfCore
// (planTiledSearch + searchTiled, the path of `synthtrack-cli search --preprocessed`, on the CPU). Raw frames
// that do not fit are refused with what to do.
#include <QObject>
#include <QString>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "st/common/memory_budget.hpp"
#include "st/common/progress.hpp"

class QLabel;
class QWidget;

namespace st::pipeline {
struct OutOfCoreCube;
}

namespace st::ui {

class MainWindow;

class OutOfCoreController : public QObject {
  Q_OBJECT
 public:
  /// Adds Run > Memory limit…, the status-bar label and the banner to `window` (its parent).
  explicit OutOfCoreController(MainWindow* window);
  /// The controller of `window` (made by its constructor).
  static OutOfCoreController* of(const MainWindow* window);

  [[nodiscard]] MemoryBudget budget() const;
  /// Sets the limit ("" = default). Throws st::InputError for a size parseMemorySize refuses.
  void setMemoryLimit(const QString& limit);
  /// The observation open out of core, or null.
  [[nodiscard]] const std::shared_ptr<const pipeline::OutOfCoreCube>& cube() const noexcept { return m_cube; }
  [[nodiscard]] bool active() const noexcept { return m_cube != nullptr; }

  /// In the load job's worker: null when `inputs` fit `budget` in memory (load them as usual); else the
  /// apply closure of an out-of-core opening. Throws st::InputError for raw frames over the budget.
  std::function<void()> openIfNeeded(const std::vector<std::string>& inputs, std::size_t budget,
                                     const QString& label, ProgressSink& progress, CancelToken& cancel);
  /// Leaves out-of-core mode (another observation is loaded in memory).
  void clear();
  /// Starts the out-of-core search with the Search dock's grid and parameters.
  void runSearch();

 private:
  void update();

  MainWindow* m_window;
  std::shared_ptr<const pipeline::OutOfCoreCube> m_cube;
  QLabel* m_label = nullptr;
  QWidget* m_banner = nullptr;
  QLabel* m_bannerText = nullptr;
};

}  // namespace st::ui
