"""The paper's question with neural networks: classic control and MinAtar."""
