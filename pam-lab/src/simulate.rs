//! Driving the model with measured pressure and load.
