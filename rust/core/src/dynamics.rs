//! Rigid-body dynamics of a serial arm. Work in progress: see issue [controller].
