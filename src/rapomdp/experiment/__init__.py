"""The closed loop (paper Sec. 5.2): episodes, the methods compared, metrics, figures, report."""
