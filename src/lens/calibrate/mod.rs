//! Calibrating a lens from pictures of a board: the board itself (`board`: its geometry, its
//! picture to print, its shade for the synthetic scene) and finding it in frames (`detect`).
//! Off the frame path: this produces lens.cal entries, which the renderers then use.

pub mod board;
pub mod detect;

pub use board::{Board, BoardError};
pub use detect::{Finder, Sighting};
