//! The 1 kHz task-space P-D + DOB controller. Work in progress: see issue [controller].
