"""The steps of a block's chain that read or write the block: one entry point per Processing algorithm
(read the block through algorithms.block.Block, call the science packages, store the results). This
package sits above the science packages and the block store, which never import it."""
