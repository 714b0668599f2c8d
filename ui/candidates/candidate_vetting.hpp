#pragma once
// Vetting vocabulary of the GUI (issue 8 §2): the single-key shortcuts of the candidates table, the text and
// colour of each label. The labels themselves are st::session::Label / ArtifactReason (session.hpp), so the
// session file, the reports (session_report.hpp colours DS9 marks the same way) and the GUI agree.
#include <QColor>
#include <QString>
#include <optional>

#include "st/session/session.hpp"

namespace st::ui {

/// What one key does in the candidates table.
struct VettingKey {
  session::Label label = session::Label::Unvetted;
  session::ArtifactReason reason = session::ArtifactReason::None;
};

/// The label a key gives (Qt::Key value, no modifier): R real, U unsure, C charge leakage, D diffraction,
/// X cosmic ray, G ghost, O other artifact, 0 / Backspace / Delete clear (unvetted); nullopt for any other
/// key.
[[nodiscard]] std::optional<VettingKey> vettingKeyFor(int key) noexcept;
/// Key that opens the note editor (N).
inline constexpr int kNoteKey = 'N';

/// Rich-text list of the shortcuts, for tooltips and the help button.
[[nodiscard]] QString vettingShortcutHelp();

/// "real", "artifact", "unsure", "" (unvetted).
[[nodiscard]] QString labelText(session::Label label);
/// "charge leakage", "diffraction", "cosmic ray", "ghost", "other", "".
[[nodiscard]] QString reasonText(session::ArtifactReason reason);
/// Row tint of a label: real green, artifact red, unsure yellow (session_report's DS9 colours); invalid for
/// unvetted (no tint). `strong` gives the saturated colour for the label cell itself.
[[nodiscard]] QColor labelColour(session::Label label, bool strong);

}  // namespace st::ui
