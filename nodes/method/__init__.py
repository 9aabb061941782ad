"""The paper's steps as pure functions of arrays (``light``, ``remap``, ``sfs_init``,
``robust_fit``, ``shadow``, ``albedo``, ``relight``) and their thin node wrappers (``nodes``),
which read and write the frame keys of ``keys``."""
