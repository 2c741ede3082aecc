//! Runs with no window: a recording replayed step by step (`replay`), the player bot
//! that plays a level to its end and records the run (`autoplay`), and what ears at a
//! place hear (`listen`). Outside the frame:
//! both drive the frame driver's own fixed step (`frame::Engine::step`) and never render.
//! The command line and the window (the editor's play-check) both call them; nothing here
//! knows either.

pub mod autoplay;
pub mod listen;
pub mod replay;
