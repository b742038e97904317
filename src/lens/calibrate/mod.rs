//! Calibrating a lens from pictures of a board: the board itself (`board`: its geometry, its
//! picture to print, its shade for the synthetic scene), finding it in frames (`detect`), and
//! fitting a lens to the corners found (`fit`).
//! Off the frame path: this produces lens.cal entries, which the renderers then use.

pub mod board;
pub mod detect;
pub mod fit;

pub use board::{Board, BoardError};
pub use detect::{Finder, Sighting};
