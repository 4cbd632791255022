"""What was measured: campaigns, traces, a part's points, and the residuals read from them."""
