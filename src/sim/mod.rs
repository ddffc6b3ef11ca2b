//! Synthetic trees and capture sessions with ground truth: the project's own
//! test bench, since no public motion capture of trees exists.
