//! Layer coupling: LK14 constraint kernels and the KCK18 surface walk.
//!
//! Not implemented yet (issues 4 and 6). The schedule's ConstraintResample, ConstraintAdjust and
//! AnchorWalk stages have no systems until then, and no scene can declare kernels or anchors.
