#pragma once
// The memory budget of the GUI and cubes larger than it (issue 20 item 4), beside MainWindow (driving it
// through its public API).
//
// - Run > Memory limit… sets the budget (QSettings "memory/limit", the CLI's --memory-limit syntax: 8G, 500M;
//   empty = 70% of the available memory, st::resolveMemoryBudget); a permanent status-bar label shows it.
// - Opening inputs: MainWindow::openInputs asks CoreServices::planOpen (pipeline::planOpen) in the load job's
//   worker. A pre-processed cube (synthtrack-cli preprocess, or search --keep-scratch) that does not fit is
//   opened OUT OF CORE here (open(), still in the worker): pipeline::openOutOfCore reads its header, times
//   and a corner; the view shows the mean of all frames summed in strips of rows (pipeline::stackOutOfCore,
//   CFITSIO subset reads); a banner above the image and the status label say so, with the budget.
// - Raw frames whose in-memory pre-processing does not fit (planOpen refuses them) are pre-processed OUT OF
//   CORE in the load job's worker (openRaw): core's pipeline::planRawOutOfCore + preprocessRawOutOfCore, as
//   `synthtrack-cli search` does (strips of rows, the calibration folders offered beside the frames), into a
//   filtered cube in scratchDir() that is then opened out of core as above and removed when another
//   observation is opened or the window closes. The GUI thread only applies the result.
// - Search (MainWindow::runSearch -> runSearch()) runs pipeline::searchOutOfCore, the tiled CPU search of
//   `synthtrack-cli search --preprocessed`, as a JobRunner job: the GUI thread only starts it and applies the
//   result; progress and cancel are the runner's.
// - The central "stack at velocity" (a selected candidate's velocity) is summed in strips in a thread of
//   the global pool (requestStack); a newer request cancels the older one.
// - What needs the whole cube in memory (live stacks, the inspector's stamps and checks, co-moving fits,
//   figures of stamps) says it is unavailable: PreparedView::outOfCore is set.
#include <QFutureWatcher>
#include <QObject>
#include <QString>
#include <QStringList>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "st/common/image.hpp"
#include "st/common/memory_budget.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"

class QLabel;
class QWidget;

namespace st::pipeline {
struct OutOfCoreCube;
struct OpenPlan;
}

namespace st::ui {

class MainWindow;

class OutOfCoreController : public QObject {
  Q_OBJECT
 public:
  /// Adds Run > Memory limit…, the status-bar label and the banner to `window` (its parent).
  explicit OutOfCoreController(MainWindow* window);
  ~OutOfCoreController() override;
  /// The controller of `window` (made by its constructor).
  static OutOfCoreController* of(const MainWindow* window);

  [[nodiscard]] MemoryBudget budget() const;
  /// Sets the limit ("" = default). Throws st::InputError for a size parseMemorySize refuses.
  void setMemoryLimit(const QString& limit);
  /// The observation open out of core, or null.
  [[nodiscard]] const std::shared_ptr<const pipeline::OutOfCoreCube>& cube() const noexcept { return m_cube; }
  [[nodiscard]] bool active() const noexcept { return m_cube != nullptr; }

  /// In the load job's worker: opens the prepared cube `inputs` out of core (`plan`: planOpen said so) and
  /// returns the apply closure (GUI thread): the mean image as the raw cube, a PreparedView with outOfCore
  /// set, the data's default grid, the banner. Throws what pipeline::openOutOfCore throws, st::Cancelled.
  std::function<void()> open(const std::vector<std::string>& inputs, std::size_t budgetBytes,
                             const QString& label, const pipeline::OpenPlan& plan, ProgressSink& progress,
                             CancelToken& cancel);
  /// In the load job's worker: raw frames `inputs` that planOpen refused (their in-memory pre-processing does
  /// not fit `budgetBytes`) pre-processed out of core (pipeline::planRawOutOfCore, preprocessRawOutOfCore)
  /// with the calibration frames `calibration` (bias, dark, flat -> files or folders), into a filtered cube
  /// in scratchDir(), then opened as open() opens a prepared cube. Throws st::InputError when not even a
  /// strip fits (naming the need and the budget), what pre-processing throws, st::Cancelled; the scratch cube
  /// is removed then, and when the returned closure is dropped without being run.
  std::function<void()> openRaw(const std::vector<std::string>& inputs, std::size_t budgetBytes,
                                const QString& label, const std::map<std::string, QStringList>& calibration,
                                ProgressSink& progress, CancelToken& cancel);
  /// Where openRaw writes its filtered cube: QSettings "memory/scratch" when set, else the temporary folder.
  [[nodiscard]] static QString scratchDir();
  /// The scratch cube of the observation open now (openRaw), or empty.
  [[nodiscard]] const std::string& scratchCube() const noexcept { return m_scratch; }
  /// Run > Memory limit… (and the banner's button): asks for the limit, stores it.
  void askMemoryLimit();
  /// Leaves out-of-core mode (another observation is loaded in memory).
  void clear();
  /// Starts the out-of-core search with the Search dock's grid and parameters (false while a job runs).
  bool runSearch();
  /// Sums the IPSA stack at `v` in strips in a worker thread; stackReady follows unless a newer request or
  /// clear() came first.
  void requestStack(Velocity v);

 signals:
  /// The sum of all frames at `v` (image pixels), for the central view.
  void stackReady(const std::shared_ptr<const st::Image>& sum, st::Velocity v, double elapsedS);

 private:
  struct ScratchFile;
  /// open() and openRaw(): the prepared cube `inputs` opened out of core; `why` and `need` for the banner,
  /// `notes` added to the summary, `scratch` (may be null) owned by the controller once applied.
  std::function<void()> openCube(const std::vector<std::string>& inputs, std::size_t budgetBytes,
                                 const QString& label, const std::string& why, double need,
                                 const std::vector<std::string>& notes, std::shared_ptr<ScratchFile> scratch,
                                 ProgressSink& progress, CancelToken& cancel);
  void update();
  void cancelStack();
  void removeScratch();

  MainWindow* m_window;
  std::shared_ptr<const pipeline::OutOfCoreCube> m_cube;
  double m_needBytes = 0.0;  ///< what holding the cube in memory would need
  std::string m_scratch;     ///< openRaw's filtered cube, removed by clear() and the destructor
  QLabel* m_label = nullptr;
  QWidget* m_banner = nullptr;
  QLabel* m_bannerText = nullptr;
  struct StackOutcome {
    std::shared_ptr<const Image> sum;  ///< null when cancelled or failed
    Velocity v;
    double elapsedS = 0.0;
    QString error;
  };
  QFutureWatcher<StackOutcome> m_stackWatcher;
  std::shared_ptr<CancelToken> m_stackCancel;
};

}  // namespace st::ui
