"""The obliquity scan of Mueller, Ioannidis & Schmitt (2021): configuration,
windows and detrending, statistics, progress files, the scan, the scan
marginalised over the transit posterior, Table 5 and the paper's figures.
Imports inference, the model layer and the kernels."""
