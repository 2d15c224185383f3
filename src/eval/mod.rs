//! Distance matrices, labels and leave-one-out classification.
//!
//! (to be implemented)
