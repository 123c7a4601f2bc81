"""CMEMS / ERA5 acquisition, local NetCDF readers, canonical grids and regridding."""
