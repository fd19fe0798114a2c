<?xml version="1.0" encoding="utf-8"?>
<!DOCTYPE TS>
<TS version="2.1">
<context>
    <name>Pushbroom</name>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="36"/>
        <source>Assess accuracy (dh against a reference DEM)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="65"/>
        <source>Reference DTM/DSM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="87"/>
        <source>Reference heights</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="69"/>
        <source>Point cloud (object points)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="69"/>
        <source>Point clouds (*.las *.laz *.gpkg);;All files (*.*)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="90"/>
        <source>DEM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="91"/>
        <source>DEM heights</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="79"/>
        <source>Class raster</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="82"/>
        <source>Class polygons</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="90"/>
        <source>Class field of the polygons</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="98"/>
        <source>Slope of mountainous terrain (degrees, of the reference)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="116"/>
        <source>Point cloud heights</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="108"/>
        <source>Report</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="108"/>
        <source>HTML files (*.html)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="140"/>
        <source>dh raster (DEM input)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="145"/>
        <source>Statistics table</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="140"/>
        <source>CSV files (*.csv)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="85"/>
        <source>Simulation</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/select_tie_points.py" line="35"/>
        <source>Block</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="87"/>
        <source>Matching</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="88"/>
        <source>Adjustment</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="89"/>
        <source>Surface</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="471"/>
        <source>Threads in this process</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="472"/>
        <source>Local worker processes</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="473"/>
        <source>Dask distributed: a local cluster, or the scheduler at the address below</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="483"/>
        <source>Execution of the tiles</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="489"/>
        <source>Dask scheduler address (tcp:// or tls://host:port; empty: a local cluster)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="495"/>
        <source>Wait for a Dask worker where the cluster has none, or has lost every one (s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="503"/>
        <source>Workers (threads, processes or local Dask workers; at most {} per core are used)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="548"/>
        <source>Replace the block&apos;s {} even by far fewer (none, or below half)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="28"/>
        <source>Correction polynomials with autocalibration (Kornus et al. 2006)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="29"/>
        <source>Lagrange polynomials on orientation images (Heipke et al. 1992)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="35"/>
        <source>Bundle adjustment</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="63"/>
        <source>Free parameters (&apos;auto&apos; or comma-separated patterns)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="68"/>
        <source>Exterior orientation model of SPOT images</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="76"/>
        <source>Use the block&apos;s tie points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="81"/>
        <source>Remove flagged measurements iteratively</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="88"/>
        <source>Reference DTM for the tie point heights (Kornus et al. 2006, Table 4)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="95"/>
        <source>Heights of the reference DTM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Sigma of tie point image measurements (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Critical normalised residual (data snooping)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Maximum iterations</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Estimate variance components (tie, control image, control ground)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Automatic selection: significance threshold x/sigma</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Control point counts of the accuracy table (Heipke et al. 1992), e.g. 4,6,10</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Lagrange model: orientation images per trajectory</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Scale of the residual vectors on the map</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>Prior sigmas of orientation unknowns (pattern=sigma, ...; e.g. bias:shift=10)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="175"/>
        <source>Residual vectors of control and check points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="184"/>
        <source>sigma_0</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/select_tie_points.py" line="61"/>
        <source>Block (updated; chains the next step in a model)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/create_block.py" line="27"/>
        <source>Create block</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/create_block.py" line="46"/>
        <source>Images</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/create_block.py" line="51"/>
        <source>Orientation files (one per image, same order; found beside the images if empty)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/create_block.py" line="61"/>
        <source>DEM for the footprints (ellipsoidal heights)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/create_block.py" line="66"/>
        <source>Mean ellipsoidal height without a DEM (m, {:g} .. {:g}; empty: matched)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/create_block.py" line="77"/>
        <source>Overwrite an existing block</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/create_block.py" line="85"/>
        <source>GeoPackage (*.gpkg)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/create_block.py" line="90"/>
        <source>Footprints</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="25"/>
        <source>Fit RPC</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="43"/>
        <source>Image name (empty: every image of the block)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="51"/>
        <source>Lowest ellipsoidal height of the cube (m, {:g} .. {:g}; empty: the block&apos;s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="62"/>
        <source>Highest ellipsoidal height of the cube (m, {:g} .. {:g}; empty: the block&apos;s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="73"/>
        <source>Overwrite existing _RPC.TXT files, also beside an image with its own RPC</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="80"/>
        <source>Image grid points along columns and rows</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="80"/>
        <source>Height levels</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="98"/>
        <source>Output folder (empty: beside each image raster, where it carries no RPC of its own)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/fit_rpc.py" line="116"/>
        <source>RPC files (_RPC.TXT)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="34"/>
        <source>Replace the block&apos;s points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="35"/>
        <source>Merge: update points with the same id, add the others</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="41"/>
        <source>Import control and check points (CSV)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="67"/>
        <source>Point file (CSV)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="67"/>
        <source>CSV files (*.csv *.txt);;All files (*.*)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="74"/>
        <source>CRS of x/y columns (lon/lat columns are WGS 84)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="82"/>
        <source>Heights</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="83"/>
        <source>Role of points without one in the file</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="91"/>
        <source>Check point ids (comma-separated)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="97"/>
        <source>Import mode</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="105"/>
        <source>Default sigma east (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="105"/>
        <source>Default sigma north (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="105"/>
        <source>Default sigma height (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="105"/>
        <source>Default sigma of the image measurements (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="105"/>
        <source>Measurement column suffix (&apos;_meas&apos; for the simulator&apos;s points.csv)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="105"/>
        <source>Keep points the block&apos;s images and measurements disagree with (a warning)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="105"/>
        <source>points and measurements</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="149"/>
        <source>Control and check points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="155"/>
        <source>Control points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="156"/>
        <source>Check points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="157"/>
        <source>Image measurements</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="203"/>
        <source>Export control and check points (CSV)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="212"/>
        <source>Point file</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="25"/>
        <source>WGS 84 ellipsoidal height</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="25"/>
        <source>EGM96 (orthometric) height</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="30"/>
        <source>TIN of the points (sparse points: region growing, coarse-to-fine)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="30"/>
        <source>Per-cell median (dense points: the dense matching strategy)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="38"/>
        <source>Interpolate DEM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="112"/>
        <source>Point cloud</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="71"/>
        <source>Point clouds (*.las *.laz *.gpkg *.shp *.geojson);;All files (*)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="78"/>
        <source>Breaklines (3-D lines)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="86"/>
        <source>Output CRS (empty: the UTM zone of the points)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="91"/>
        <source>Cell size (output CRS units)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="96"/>
        <source>Method</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="101"/>
        <source>Height datum</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="107"/>
        <source>Point cloud CRS (empty: the file&apos;s own)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="107"/>
        <source>Maximum triangle edge (empty: 3 cells or 2.5 point spacings)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="107"/>
        <source>Blunder threshold k (robust sigmas; 0: no filter)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="107"/>
        <source>Blunder filter iterations</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="107"/>
        <source>Tile size (cells)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="107"/>
        <source>Per-cell method: unrefined points where a cell has no refined one</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="107"/>
        <source>Per-cell method: borrow points within this many cells (0: none)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="107"/>
        <source>Per-cell method: fill gaps within this many cells (0: none)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="162"/>
        <source>Precision raster</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="167"/>
        <source>Points per cell (per-cell method)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="175"/>
        <source>Cell mask (per-cell method: 0 own points, 2 borrowed, 1 filled, 255 gap)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="183"/>
        <source>Points in the DEM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="184"/>
        <source>Gap cells filled</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/interpolate_dem.py" line="185"/>
        <source>Blunders (outliers) removed</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="26"/>
        <source>Mass points (pushbroom:matchpoints)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="26"/>
        <source>Tie points (pushbroom:selecttiepoints)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="34"/>
        <source>Intersect points (point cloud)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="60"/>
        <source>Points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="65"/>
        <source>Output CRS (empty: the block&apos;s UTM zone)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="78"/>
        <source>Sigma of the image coordinates (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="78"/>
        <source>Maximum iterations per point</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="78"/>
        <source>Statistical outlier removal: neighbours k (0: off)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="78"/>
        <source>Statistical outlier removal: factor n (mean distance &gt; mu + n sigma)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="112"/>
        <source>LAS files (*.las);;LAZ files (*.laz);;GeoPackage (*.gpkg)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="127"/>
        <source>Point layer (GeoPackage output)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="132"/>
        <source>Points written</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="167"/>
        <source>Object points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="35"/>
        <source>Automatic: interest points matched along the path predicted by the sensor models</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="35"/>
        <source>The block&apos;s tie points (pushbroom:selecttiepoints)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="35"/>
        <source>Both: the block&apos;s tie points and automatic seeds</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="48"/>
        <source>Region growing (Otto &amp; Chau; Kornus et al. 2006)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="49"/>
        <source>Coarse-to-fine multi-primitive with MPGC (Zhang &amp; Gruen)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="50"/>
        <source>Dense: semi-global matching on epipolar tiles, refined by LSM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="61"/>
        <source>Match points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="107"/>
        <source>Matching strategy</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="260"/>
        <source>Coarse-to-fine: grid point spacing at full resolution (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="267"/>
        <source>Coarse-to-fine: minimum correlation coefficient at full resolution</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="275"/>
        <source>Coarse-to-fine: tile size of the reference image (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="282"/>
        <source>Coarse-to-fine: matched edges as extra points and breaklines</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="293"/>
        <source>Dense: tile size of the reference image (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="301"/>
        <source>Dense: a point every ... px of the reference image</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="308"/>
        <source>Dense: refine the positions by LSM in the original images (TEMPLATE px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="327"/>
        <source>Dense: SGM penalty P1 (a disparity change of 1 px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="334"/>
        <source>Dense: SGM penalty P2 (a larger change)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="131"/>
        <source>mass points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="140"/>
        <source>Summary per point group (CSV)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="431"/>
        <source>Mass points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="158"/>
        <source>Mass point folder (index and parts)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="32"/>
        <source>ellipsoidal (WGS 84)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="32"/>
        <source>EGM96</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="37"/>
        <source>Orthorectify image</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="65"/>
        <source>Block (empty: the image&apos;s own orientation)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="73"/>
        <source>Image name in the block</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="78"/>
        <source>Image (without a block)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="83"/>
        <source>Orientation file (empty: found beside the image)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="99"/>
        <source>Output CRS (empty: UTM zone of the footprint)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="104"/>
        <source>Cell size in CRS units (empty: ground sampling distance)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="114"/>
        <source>Resampling</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="122"/>
        <source>Occluded cells as nodata</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="127"/>
        <source>Bound of the coarse-grid interpolation error (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="141"/>
        <source>Orthoimage</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="150"/>
        <source>Achieved interpolation error bound (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="153"/>
        <source>Cells with image values</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/select_tie_points.py" line="22"/>
        <source>Select tie points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/select_tie_points.py" line="36"/>
        <source>Grid cell size (px of the reference image)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/select_tie_points.py" line="45"/>
        <source>Lowest point group accepted (1, 2 or 3)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/select_tie_points.py" line="55"/>
        <source>tie points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/select_tie_points.py" line="56"/>
        <source>Tie points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/select_tie_points.py" line="66"/>
        <source>Tie point folder (index and parts)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="25"/>
        <source>SPOT-5 along-track triplet (HRS1 +20 deg, HRG nadir, HRS2 -20 deg)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="28"/>
        <source>SPOT 1-4 across-track pair (two passes, B/H about 0.5)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="35"/>
        <source>Simulate scene</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="66"/>
        <source>Configuration</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="74"/>
        <source>Scene size (km)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="84"/>
        <source>Random seed</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="85"/>
        <source>Radiometric resolution (bits)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="93"/>
        <source>Control/check point candidates</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="102"/>
        <source>Blunders among the point measurements</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Image noise sigma (DN at 8 bit)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Fractal terrain detail (x 4 m, 0 = off)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Forest and buildings in the DSM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Point measurement noise (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Paint bright markers at the point candidates</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Scale of the injected orientation errors (0: supplied = truth)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Ground grid cell (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Look angles and line period from this METADATA.DIM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="111"/>
        <source>Ground reflectance from this orthoimage</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="167"/>
        <source>Output folder</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="168"/>
        <source>Images (IMAGERY.TIF)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="170"/>
        <source>True DSM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="171"/>
        <source>True DTM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="172"/>
        <source>Land-cover classes</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="173"/>
        <source>True orthoimage</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="176"/>
        <source>Control/check point candidates (CSV)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="179"/>
        <source>Truth file (JSON)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/simulate_scene.py" line="180"/>
        <source>Scene folder</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="116"/>
        <source>reference DTM/DSM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="442"/>
        <source>Ellipsoidal (WGS 84)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="443"/>
        <source>Orthometric (EGM96 geoid; needs PROJ&apos;s EGM96 grid)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/bundle_adjust.py" line="98"/>
        <source>reference DTM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/dem_nodata.py" line="16"/>
        <source>Nodata value of the {} (voids its file does not flag, e.g. -32768)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="29"/>
        <source>Control point</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/import_points.py" line="30"/>
        <source>Check point</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="28"/>
        <source>Bilinear</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="29"/>
        <source>Bicubic</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="115"/>
        <source>Images: reference (nadir), forward[, backward]; empty: all</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="123"/>
        <source>Lowest ellipsoidal terrain height (m; empty: the block&apos;s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="123"/>
        <source>Highest ellipsoidal terrain height (m; empty: the block&apos;s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="166"/>
        <source>Region growing: seeds</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="172"/>
        <source>LSM template size (px, odd; region growing, dense)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="179"/>
        <source>Region growing: STEP, the distance of the neighbours (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="188"/>
        <source>Region growing: a wider template where the first fails (px; 0: off)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="195"/>
        <source>Region growing: minimum correlation coefficient</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="203"/>
        <source>Region growing: largest semi-major axis of the error ellipse (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="210"/>
        <source>Region growing: largest shift from the initial values (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="217"/>
        <source>Region growing: largest number of LSM iterations</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="224"/>
        <source>Region growing: tile size of the reference image (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="231"/>
        <source>Region growing: group 3 consistency test, k robust sigma</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="238"/>
        <source>Region growing: grow combination (b) where (a) found no points</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="243"/>
        <source>Region growing: refine the group 3 points by MPGC</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="248"/>
        <source>Region growing: MPGC with support weights (for DEMs)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="313"/>
        <source>Dense: a wider LSM template where TEMPLATE fails (px, odd; 0: off)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/match_points.py" line="320"/>
        <source>Dense: refine a triplet&apos;s three-ray points by MPGC (matching about 2.5x slower)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="108"/>
        <source>Assess the DEM co-registered to the reference too (before and after)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="116"/>
        <source>Co-register with a tilt (a plane) too</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="34"/>
        <source>Co-register DEM to a reference (Nuth and Kääb)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="65"/>
        <source>DEM to co-register</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="67"/>
        <source>Reference DEM (DTM/DSM, lidar)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="71"/>
        <source>Unstable terrain mask (non-zero cells left out: forest, water, changes)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="78"/>
        <source>Largest slope of stable terrain (degrees, of the reference)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="88"/>
        <source>Fit a tilt (a plane) too</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="98"/>
        <source>Outliers: |dh - median| beyond this many NMAD</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="98"/>
        <source>Convergence: horizontal step below (cells)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="98"/>
        <source>Largest number of iterations</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="98"/>
        <source>reference DEM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="126"/>
        <source>Co-registered DEM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="129"/>
        <source>Co-registration report</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="138"/>
        <source>Shift east (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="138"/>
        <source>Shift north (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="138"/>
        <source>Vertical shift (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="138"/>
        <source>NMAD of dh on stable terrain before (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="138"/>
        <source>NMAD of dh on stable terrain after (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/base.py" line="450"/>
        <source>Raster outputs as Cloud-Optimised GeoTIFF (COG)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="70"/>
        <source>Colour the points from the images (LAS colour fields)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="119"/>
        <source>EPT index of the point cloud (opens in QGIS without PDAL)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/intersect_points.py" line="162"/>
        <source>Object points (EPT)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="33"/>
        <source>Merge DEMs (co-registered, weighted by precision)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="61"/>
        <source>DEMs (the first one is the others&apos; frame)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="66"/>
        <source>Precision rasters (one per DEM, in the DEMs&apos; order)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="74"/>
        <source>Heights of the DEMs</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="75"/>
        <source>Co-register the DEMs first</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="80"/>
        <source>Reference to co-register to (empty: the first DEM)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="88"/>
        <source>Co-register with a tilt too</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="91"/>
        <source>Output CRS (empty: the first DEM&apos;s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="96"/>
        <source>Cell size in CRS units (empty: the first DEM&apos;s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="106"/>
        <source>Outliers: farther from the median than K (spread, precision)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="106"/>
        <source>Cells over which a DEM&apos;s weight rises from its edge</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="127"/>
        <source>Merged DEM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="128"/>
        <source>Precision raster of the merged DEM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="136"/>
        <source>Heights merged per cell</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="141"/>
        <source>Cells with a height</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/merge_dems.py" line="142"/>
        <source>Outlying heights left out</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="21"/>
        <source>Extract DTM and height above ground (Bulldozer)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="41"/>
        <source>DSM (projected CRS, metres)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="44"/>
        <source>Largest object above the ground (m)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="53"/>
        <source>Steepest ground slope (%)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="53"/>
        <source>DSM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="53"/>
        <source>Tile side (cells)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="74"/>
        <source>DTM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="75"/>
        <source>Height above ground (DSM - DTM)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/extract_dtm.py" line="80"/>
        <source>Bulldozer&apos;s mask (1 nodata filled, 2 pit filled)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/assess_accuracy.py" line="116"/>
        <source>Unstable terrain left out of the co-registration (non-zero cells)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/coregister_dem.py" line="91"/>
        <source>Fit the horizontal shift (off: the vertical offset and the tilt only)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../plugin/algorithms/orthorectify.py" line="142"/>
        <source>Occlusion mask (0 seen, 1 occluded by the DEM&apos;s surface, 255 outside)</source>
        <translation type="unfinished"></translation>
    </message>
</context>
</TS>
