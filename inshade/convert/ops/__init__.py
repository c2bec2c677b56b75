"""Op lowerings, one family per module, registered in the tables of ``inshade.convert.registry``:
``torch_*`` for ATen ops (inshade.export), ``onnx_*`` for ONNX op types (inshade convert), and
``common`` for what both share. Every lowering is called as ``lower(walk, node, *inputs,
**attributes)``: ``walk`` is the graph walk (its ``L`` the Lowering, ``batch`` the batch size,
``array(c)`` a constant as float32 numpy), ``node`` the source's node."""
