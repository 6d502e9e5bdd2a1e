//! The `.vtu` writer with its readers (appended, inline) and the `.pvd` collections.

mod appended;
mod inline;
