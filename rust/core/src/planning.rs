//! Constrained RRT (the GAN paper's Algorithm 1). Work in progress: see issue [crrt].
