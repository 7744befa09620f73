//! Readers and writers of motion and result files. (In progress.)
